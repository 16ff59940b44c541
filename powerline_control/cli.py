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
    calibrate    the span's tension and EI with their uncertainty, from a record (--record)
    study        a grid of scenario variants (--vary KEY=V1,V2 ...), a table of results
    report       run a scenario and write only its HTML report
    scenario     list the shipped scenarios, or print one as a commented TOML template

This module imports only the standard library at import time: ``--help`` and ``scenario`` stay
fast, and numpy, SciPy, python-control, cvxpy, CasADi and matplotlib load inside the verbs. The
numerical work runs under one BLAS thread (threadpoolctl, in the verb's scope only): its matrices
are small, and two contending threads on a 2-core machine made ``run`` 2.5x slower.

Test seam: ``_numerics``: the verbs' BLAS scope, tested to limit the threads inside it only.
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
from collections.abc import Sequence
from pathlib import Path

from .errors import InputError, PowerlineControlError

__all__ = ["main", "EXIT_OK", "EXIT_NUMERICAL", "EXIT_USAGE", "EXIT_INTERRUPTED"]

#: Exit status: success.
EXIT_OK = 0
#: Exit status: numerical trouble (unstable or singular model, infeasible plan, solver failure).
EXIT_NUMERICAL = 1
#: Exit status: bad input or usage (scenario, arguments, output folder).
EXIT_USAGE = 2
#: Exit status: interrupted with Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130

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


# ----------------------------------------------------------------------------- outputs

class _Output:
    """An output folder checked before the run; it never overwrites files it did not write.

    A folder that does not exist yet is created only when the first file is written: a run
    refused before it writes anything leaves nothing behind (and a folder the user made is
    never removed).
    """

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
        missing = []   # the folders this check creates, innermost first
        for folder in (path, *path.parents):
            if folder.exists():
                break
            missing.append(folder)
        try:
            path.mkdir(parents=True, exist_ok=True)
            probe = path / ".powerline-control-write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as exc:
            raise InputError(f"--out {str(path)!r} is not a writable folder: "
                             f"{exc.strerror or exc}.") from None
        finally:
            for folder in missing:   # created for the probe: removed until a file is written
                with contextlib.suppress(OSError):
                    folder.rmdir()   # only ever an empty folder this check made

    def _manifest(self) -> set[str]:
        try:
            return set(json.loads((self.path / MANIFEST).read_text())["files"])
        except (OSError, ValueError, KeyError, TypeError):
            return set()

    def file(self, name: str) -> Path:
        """The path of an output file, recorded in the manifest (the folder created now)."""
        self.path.mkdir(parents=True, exist_ok=True)
        self.written.append(name)
        (self.path / MANIFEST).write_text(json.dumps(
            {"written_by": "powerline-control", "files": sorted(set(self.written)
                                                                | self._manifest())}))
        return self.path / name


def _write_outputs(out: _Output, result, *, full: bool = True, records: bool = False) -> list:
    """Write what the run produced (the finished stages' outputs, also after a failure)."""
    from .scenario import scenario_to_toml

    if full:
        out.file("scenario.toml").write_text(scenario_to_toml(result.scenario))
        if result.identification is not None:
            from .output.io import save_model

            save_model(out.file("dmd_model.npz"), result.identification.design.model)
        if records and result.records is not None:
            _write_records(out, result)
        out.file("summary.json").write_text(json.dumps(result.to_dict(), indent=2,
                                                       default=float))
    result.report(out.file("report.html"))
    return out.written


def _write_records(out: _Output, result) -> None:
    """The simulated records at every node, as record.npz + record.csv (and the training run)."""
    from .output.records import Record, save_record

    recs = result.records
    pairs = [("record", recs.test)]
    if recs.train is not recs.test:
        pairs.append(("training_record", recs.train))
    for name, snap in pairs:
        out.file(f"{name}.npz")
        out.file(f"{name}.csv")
        save_record(out.path / name, Record(snap.t, snap.x, snap.displacement,
                                            f"simulated ({result.scenario.name})",
                                            truth=snap.true_displacement))


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


def _print_sections(console: _Console, result) -> None:
    # The verdict first, as on the report's first screen; then every section's rows.
    verdict = result.verdict()
    if verdict.headlines or verdict.caveats:
        console.out("Summary")
        for line in verdict.headlines:
            console.out(f"  {line.label:<42} {line.text} {line.verdict}")
        for caveat in verdict.caveats:
            console.out(f"  caveat: {caveat.text}")
    for section in result.sections():
        console.out(section["title"])
        for row in section["rows"]:
            console.out(f"  {row[0]:<42} {row[1]}")


def _verb_stages(args, console: _Console, *, full: bool = True) -> int:
    from .scenario import check_severity_inputs, load_scenario
    from .scenario.pipeline import VERB_STAGES, run_scenario, stage_plan

    scenario = load_scenario(args.scenario)
    if args.command == "severity":
        check_severity_inputs(scenario, str(args.scenario or "<default>"))
    record = None
    if getattr(args, "record", None) is not None:
        from .output.records import load_record

        record = load_record(args.record)
    wind_record = getattr(args, "wind_record", None)
    if wind_record is None and "fatigue" in VERB_STAGES[args.command]:
        wind_record = scenario.severity.wind_record
    if wind_record is not None:  # read (and refused) before anything runs or is written
        from .scenario.pipeline import read_wind_record

        wind_record = read_wind_record(wind_record)[0]
    browser = None
    if getattr(args, "pdf", False):
        if not getattr(args, "out", None):
            raise InputError("--pdf needs --out (the folder the report is written to).")
        browser = _browser()
        if browser is None:
            raise InputError("--pdf needs Chromium (chromium, chromium-browser or "
                             "google-chrome on the PATH); report.html alone needs nothing.")
    output = _Output(args.out, force=args.force) if getattr(args, "out", None) else None
    stages = VERB_STAGES[args.command]
    start = time.perf_counter()
    n_stages = len(stage_plan(scenario, stages, wind_record=wind_record)) + (output is not None)
    with _numerics(), _Progress(console, n_stages) as progress:
        result = run_scenario(scenario, stages=stages, record=record, wind_record=wind_record,
                              progress=progress.stage, keep_partial=True)
        _print_sections(console, result)
        written = []
        if output is not None:
            progress.stage("drawing the figures and writing the report")
            written = _write_outputs(output, result, full=full,
                                     records=args.command in ("simulate", "identify"))
            if browser is not None and result.ok:
                _print_pdf(browser, output.path / "report.html", output.file("report.pdf"))
                written = output.written
    numbers = result.to_dict()
    numbers["elapsed_s"]["total"] = round(time.perf_counter() - start, 2)
    if result.failure is not None:
        return _failed(console, result, numbers, output, written)
    _finish(console, numbers, output, written)
    return EXIT_OK


def _bad_input(error: BaseException) -> bool:
    """Bad input (exit 2): the package's InputError (its subclasses too) and FileFormatError (a
    file the user gave). Any other error, a ValueError from SciPy or numpy included, is
    numerical trouble (exit 1): the input was accepted, the computation failed."""
    from .errors import FileFormatError

    return isinstance(error, InputError | FileFormatError)


def _failed(console: _Console, result, numbers: dict, output, written) -> int:
    """One line on stderr for a failed stage; the finished stages' outputs are on disk."""
    failure = result.failure
    error = failure.error
    code = EXIT_USAGE if _bad_input(error) else EXIT_NUMERICAL
    kind = "error" if code == EXIT_USAGE else "numerical trouble"
    kept = "" if output is None else (f" (stage {failure.stage} failed; the finished stages' "
                                      f"results are in {output.path}/)")
    if console.debug:
        import traceback

        traceback.print_exception(error)
    print(f"powerline-control: {kind}: {failure.message}{kept}", file=sys.stderr)
    if console.as_json:
        print(json.dumps({**numbers, "error": failure.message, "exit_code": code},
                         indent=2, default=float))
    return code


def _finish(console, numbers, output, written):
    if console.as_json:
        if output is not None:
            numbers = {**numbers, "out": str(output.path), "files": sorted(set(written))}
        print(json.dumps(numbers, indent=2, default=float))
        return
    if output is not None:
        console.out(f"Results written to {output.path}/ ({', '.join(sorted(set(written)))})")
    if console.quiet:
        headline = {k: numbers[k] for k in ("vibration_reduction", "error_unmeasured_percent")
                    if k in numbers}
        print("Done." + "".join(f" {k} = {v:.3g}" for k, v in headline.items()))
    else:
        console.out(f"Done in {numbers['elapsed_s'].get('total', 0):.1f} s.")


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


def _verb_calibrate(args, console: _Console) -> int:
    """The scenario's span calibrated from --record, or from its true line simulated."""
    from .errors import CalibrationWarning
    from .scenario import load_scenario
    from .scenario.calibrate import calibrate_scenario

    scenario = load_scenario(args.scenario)
    record = None
    if args.record is not None:
        from .output.records import load_record

        record = load_record(args.record)
    with _numerics(), warnings.catch_warnings():
        # what the record cannot tell is in the summary's and the JSON's warnings
        warnings.simplefilter("ignore", CalibrationWarning)
        result = calibrate_scenario(scenario, record, progress=console.note)
    cal = result.calibration
    if console.as_json:
        print(json.dumps(result.to_dict(), indent=2))
    elif console.quiet:
        print(f"Done. tension = {cal.tension:.6g} +- {cal.tension_std:.2g} N")
    else:
        console.out(result.summary())
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
    from .scenario.pipeline import VERB_STAGES, run_scenario

    # Grid keys are identifiers (section__key) so that any executor can pass them on.
    overrides = {key.replace("__", "."): value for key, value in overrides.items()}
    scenario = load_scenario(text=_override_toml(scenario_text, overrides), source="study")
    with _numerics():
        numbers = run_scenario(scenario, stages=VERB_STAGES["estimate"]).to_dict()
    return {"error_unmeasured_percent": numbers["error_unmeasured_percent"],
            "spectral_radius": numbers["spectral_radius"],
            "sensor_positions_m": " ".join(f"{x:.4g}" for x in numbers["sensor_positions_m"])}


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
            console.out("  ".join(f"{row[k]:>22.6g}" if isinstance(row[k], float)
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


def _folder(text: str) -> Path:
    """An --out folder: a non-empty path (an empty one would write into the working folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty folder name would write into the working "
                                         "folder; give a folder name")
    return Path(text)


def _workers(text: str) -> int:
    """A positive number of worker processes."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} workers; give 1 or more")
    return value


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
            sub.add_argument("--out", type=_folder, default=None, required=out_required,
                             metavar="DIR",
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
    verb("simulate", "build the model and simulate the data (--out writes record.npz and "
         "record.csv: every node's displacement, m)")
    identify = verb("identify", "simulate, then identify a DMD model (eigenvalues, spectral "
                    "radius); --out also writes the records")
    verb("sensors", "identify, then choose the sensor positions (m) against baselines")
    estimate = verb("estimate", "choose sensors, then estimate the whole span with a Kalman "
                    "filter")
    for sub in (identify, estimate):
        sub.add_argument("--record", type=Path, default=None, metavar="FILE",
                         help="a measured record (.csv with time_s and x_<position>_m columns, "
                         "or .npz from simulate --out): its channels become the sensors and, "
                         "for estimate, the filter runs on it (NaN = missing); a channel on a "
                         "support (x = 0 or the span length), where the line does not move, "
                         "is not used")
    verb("plan", "estimate, then locate the antinodes (m) and plan the robot's move (s)")
    verb("closed-loop", "the robot driven to the antinode in closed loop, against parked")
    severity = verb("severity", "aeolian severity: antinode amplitude (mm) and clamp strain "
                    "against wind speed (m/s); with --wind-record, fatigue life over a record")
    severity.add_argument("--wind-record", type=Path, default=None, metavar="FILE",
                          help="a wind record (.csv with time, wind_speed, direction, temperature "
                          "and optionally turbulence_intensity columns): also the damage per "
                          "year and life with no damper, a fixed damper and the robot over it")
    study = verb("study", "run variants of a scenario over a grid of keys; a table of results")
    study.add_argument("--vary", action="append", metavar="SECTION.KEY=V1,V2",
                       help="a scenario key and its values (repeat for a grid)")
    study.add_argument("--workers", type=_workers, default=1,
                       help="processes to run the variants on (default 1: serial)")
    calibrate = verb("calibrate", "the span's tension and EI with their uncertainty from a "
                     "record, against the scenario's nominal span", out=False)
    calibrate.add_argument("--record", type=Path, default=None, metavar="FILE",
                           help="a measured record (.csv with time_s and x_<position>_m "
                           "columns, or .npz from simulate --out); without it, the scenario's "
                           "true line ([truth]) is simulated with its load and noise and read "
                           "at its sensors (or evenly spaced ones)")
    verb("report", "run a scenario and write only its self-contained report.html",
         out_required=True)
    scen = verb("scenario", "list the shipped scenarios, or print one (or a file) as a "
                "commented TOML template", scenario=False, out=False)
    scen.add_argument("name", nargs="?", default=None,
                      help="a shipped scenario name or a TOML file")
    return parser


_VERBS = {"demo": _verb_demo, "report": _verb_report, "scenario": _verb_scenario,
          "study": _verb_study, "calibrate": _verb_calibrate}


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
        code = EXIT_USAGE if _bad_input(exc) else EXIT_NUMERICAL
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
