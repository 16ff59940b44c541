"""The scenario pipeline's results: one frozen dataclass per stage, and ScenarioResult.

Each stage result holds that stage's own objects (the package's result types); ScenarioResult
holds them all, says in words (:meth:`ScenarioResult.sections`) and numbers
(:meth:`ScenarioResult.to_json`) what they show, and writes the report.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._results import Result, summary_of
from .._validation import check_write_path
from ..errors import InputError
from .config import Scenario

__all__ = ["ClosedLoop", "Fatigue", "Identification", "Layout", "MeasuredEstimate", "Plan",
           "Records", "ScenarioResult", "Severity", "StageFailure", "Tuning"]


@dataclass(frozen=True, eq=False)
class Records:
    """The data stage: the test record, the training record, and how they were made.

    Attributes
    ----------
    test : Snapshots
        The scenario's record; samples ``n_train:`` are held out to test the estimator.
    train : Snapshots
        The record the estimator is identified on (the identification run, or ``test`` itself).
    n_train : int
        Samples used for training.
    shaker : RandomForce or None
        The identification run's shaker (None: the scenario's own record trains).
    shaker_position : float or None
        Where it acts, m.
    measured : Record or None
        A measured record given to :func:`run_scenario` (its filter runs on it).
    simulation_s : float
        Wall-clock time of the simulation, s.
    """

    test: Any
    train: Any
    n_train: int
    shaker: Any = None
    shaker_position: float | None = None
    measured: Any = None
    simulation_s: float = 0.0


@dataclass(frozen=True, eq=False)
class Identification:
    """The estimator recipe's result and the plain-DMD fit it is compared with.

    Attributes
    ----------
    design : EstimatorDesign
        ``design_estimator``'s result: model, sensors, filter.
    plain : DMDModel
        Plain DMD (alpha = 0, one delay: the paper's eq. 11) on the same training data.
    plain_ill_conditioned : bool
        Whether that fit warned that it inverts round-off.
    sensors_given : bool
        True when the sensors came from the scenario (or the verb), not the optimisation.
    sensors_how : str
        Where the sensors came from, in words.
    forbidden : tuple of (float, float)
        The support intervals no sensor may occupy, m.
    record_model : DMDModel or None
        With a measured record: DMD on the record's own channels (its longest stretch without
        a missing sample, the design's delays and relative alpha).
    """

    design: Any
    plain: Any
    plain_ill_conditioned: bool
    sensors_given: bool
    sensors_how: str
    forbidden: tuple
    record_model: Any = None


@dataclass(frozen=True, eq=False)
class Layout:
    """One sensor layout estimated on held-out data.

    Attributes
    ----------
    name : str
        "chosen", or the baseline's label.
    nodes : tuple of int
        Sensor node indices.
    positions : tuple of float
        Sensor positions, m.
    note : str
        What the layout is, in words.
    estimate : Estimate
        The Kalman estimate on the held-out record.
    accuracy : Accuracy
        Against the true field.
    error_along_span : ndarray
        RMS error at each node over the span's RMS displacement (a fraction).
    """

    name: str
    nodes: tuple
    positions: tuple
    note: str
    estimate: Any = field(repr=False)
    accuracy: Any = field(repr=False)
    error_along_span: Any = field(repr=False)

    @property
    def error_unmeasured_percent(self) -> float:
        """RMS error at the nodes without a sensor, % of the RMS displacement."""
        return 100.0 * float(self.accuracy.relative_rms_error_unmeasured)


@dataclass(frozen=True, eq=False)
class MeasuredEstimate:
    """The designed filter run on a measured record (no truth: its consistency tells).

    Attributes
    ----------
    record : Record
        The measured record.
    nodes : tuple of int
        The node nearest each of its channels (the filter's sensors), ascending.
    estimate : Estimate
        The Kalman estimate of the whole span from it (NaN samples skipped by the filter).
    """

    record: Any = field(repr=False)
    nodes: tuple
    estimate: Any = field(repr=False)


@dataclass(frozen=True, eq=False)
class Plan:
    """Antinodes of the estimated field, the closed loop's target, and the robot's move.

    Attributes
    ----------
    antinodes, true_antinodes : list of Antinode
        Of the estimated and of the true held-out field.
    choice : Choice
        The closed loop's targeting rule on the estimated field.
    target, truth : Antinode
        The estimated and true antinodes nearest the chosen position.
    trajectory : Trajectory
        The minimum-time move from the robot's start.
    envelope : ndarray
        Largest |y| at each node over the held-out record, m.
    """

    antinodes: list
    true_antinodes: list
    choice: Any
    target: Any
    truth: Any
    trajectory: Any
    envelope: Any = field(repr=False)


@dataclass(frozen=True, eq=False)
class Tuning:
    """The robot with its absorber tuned to the load.

    Attributes
    ----------
    robot : MDR
        Tuned, placed at its start.
    mode : int
        The line's mode nearest the load frequency (1-based).
    mode_frequency : float
        Its natural frequency, Hz.
    load_frequency : float
        The load's frequency, Hz.
    antinode : float
        The antinode of that mode nearest the start, where the absorber is tuned for, m.
    how : str
        "Den Hartog" or the scenario's damping ratio.
    """

    robot: Any
    mode: int
    mode_frequency: float
    load_frequency: float
    antinode: float
    how: str


@dataclass(frozen=True, eq=False)
class ClosedLoop:
    """The closed loop stage: the tuned robot, its sensors and ``run_closed_loop``'s result.

    Attributes
    ----------
    tuning : Tuning
        The robot.
    sensors : tuple of int
        The sensors the loop reads (node indices).
    result : ClosedLoopResult
        The run.
    calibration : float
        Calibration time, s.
    sensors_how : str
        Where the sensors came from, in words (:func:`~.sensing.closed_loop_sensors`).
    unjudged : str
        Why the run is not judged in the self-limiting wind as well, in words ("" when it is:
        :func:`~.stages.wind_judgement`).
    """

    tuning: Tuning
    sensors: tuple
    result: Any = field(repr=False)
    calibration: float = 0.0
    sensors_how: str = ""
    unjudged: str = ""


@dataclass(frozen=True, eq=False)
class Severity:
    """The energy-balance severity without dampers and with the robot at each antinode.

    Attributes
    ----------
    bare, robot : SeverityResult
        Without dampers; with the robot's absorber parked at the antinode of each wind speed.
    outer_strand_diameter : float
        The outer-strand diameter used, m.
    strand_source : str
        Where it came from.
    endurance_applies : bool
        True when the conductor's family is the one the endurance strain belongs to
        (``severity.ENDURANCE_FAMILY``, ACSR): only then is its strain compared with it.
    assumptions : tuple of str
        What the study assumed where the span gives no data (the lab span's stranding, family
        and rated strength), in words.
    rated_strength : float
        The rated strength of the study's conductor, N (it normalises the self-damping law;
        NaN when the conductor carries none).
    time_domain : SeverityTimeDomain or None
        The energy balance at the scenario's aeolian wind speed checked in the time domain;
        None when not asked for, the forcing is not the wind, or the simulated wind cannot
        settle the line (``time_domain_skipped``).
    robot_frequency : float
        The frequency the robot's absorber is tuned to, sqrt(k / m_d) / 2 pi, Hz (NaN when
        unknown): it takes power from the wind speeds whose Strouhal frequency lies near it.
    time_domain_skipped : str
        Why the time-domain check was asked for and not run, in words ("" otherwise): the
        self-limiting wind cannot settle the line at that wind speed.
    """

    bare: Any
    robot: Any
    outer_strand_diameter: float
    strand_source: str
    endurance_applies: bool = True
    assumptions: tuple = ()
    rated_strength: float = float("nan")
    time_domain: SeverityTimeDomain | None = None
    robot_frequency: float = float("nan")
    time_domain_skipped: str = ""


@dataclass(frozen=True, eq=False)
class SeverityTimeDomain:
    """Self-limiting runs (:func:`~powerline_control.severity.simulate_aeolian`) at the
    scenario's aeolian wind speed, with the energy balance's powers.

    Attributes
    ----------
    bare : AeolianRun
        No damper.
    at_antinode : AeolianRun
        The robot parked at the antinode of the tone.
    near_clamp : AeolianRun
        The robot parked, as a fixed damper would be, at the harmonic-mean position of the
        1-7 m/s loop lengths from the left support (``severity.harmonic_mean_position``).
    """

    bare: Any
    at_antinode: Any
    near_clamp: Any

    @property
    def reduction(self) -> float:
        """Steady amplitude without dampers over that with the robot at the antinode."""
        return self.bare.amplitude / self.at_antinode.amplitude

    @property
    def clamp_reduction(self) -> float:
        """Steady amplitude without dampers over that with the robot parked near the clamp."""
        return self.bare.amplitude / self.near_clamp.amplitude


@dataclass(frozen=True, eq=False)
class Fatigue:
    """Fatigue over a wind record: no damper, a fixed damper and the scenario's robot.

    Attributes
    ----------
    life : FatigueOverRecord
        :func:`~powerline_control.severity.fatigue_over_record` on the severity study's span
        with the scenario's tuned robot and its ``RobotLimits``.
    record : WindRecord
        The wind record.
    source : str
        Where the record came from (its file, or "a WindRecord given to run_scenario").
    """

    life: Any = field(repr=False)
    record: Any = field(repr=False)
    source: str = ""


@dataclass(frozen=True)
class StageFailure:
    """The stage that failed and why (the stages before it finished).

    Attributes
    ----------
    stage : str
        The stage's name (see :data:`STAGES`).
    kind : str
        The exception's class name.
    message : str
        Its message, on one line.
    error : BaseException
        The exception itself.
    """

    stage: str
    kind: str
    message: str
    error: BaseException = field(repr=False, compare=False)


@dataclass(frozen=True, eq=False)
class ScenarioResult(Result):
    """Everything one scenario produced, stage by stage (None for a stage that did not run).

    Attributes
    ----------
    scenario : Scenario
        What ran.
    stages : tuple of str
        The stages asked for.
    span, model, force
        The nominal Span and LineModel (the ``[span]`` and ``[model]`` sections: what the
        engineer knows) and the load.
    true_span, true_model
        The line simulated (the scenario's ``[truth]``,
        :func:`~powerline_control.scenario.truth.true_model`): the records and the closed
        loop's plant are its; the nominal's own objects when the scenario has no ``[truth]``.
    records : Records or None
        The data.
    identification : Identification or None
        The estimator design.
    sensor_count : SensorCountStudy or None
        The predicted error against the number of sensors (each count optimised).
    sensor_count_check : SensorCountCheck or None
        The study's layouts run with the designed filter on the held-out record (what the
        report's "how many sensors" figure and the JSON show); None without a study.
    layouts : dict of str to Layout, or None
        The chosen layout ("chosen") and the baselines, estimated on held-out data.
    measured : MeasuredEstimate or None
        The filter on a measured record given to :func:`run_scenario`.
    plan : Plan or None
        Antinodes, target and move.
    closed_loop : ClosedLoop or None
        The closed loop.
    severity : Severity or None
        The severity study.
    fatigue : Fatigue or None
        Fatigue over a wind record (when one is given: ``run_scenario(wind_record=...)``).
    failure : StageFailure or None
        The stage that failed (the later ones did not run).
    elapsed : dict of str to float
        Wall-clock seconds of each stage that ran.

    Examples
    --------
    >>> from powerline_control.scenario import load_scenario
    >>> from powerline_control.scenario.pipeline import run_scenario
    >>> small = load_scenario(text="[model]\\nn_elements = 16\\n[simulation]\\nduration = 2.0\\n"
    ...                            "[estimation]\\nn_sensors = 2\\n[robot]\\nclosed_loop = 0")
    >>> result = run_scenario(small, stages=("model", "records"))
    >>> result.model.n_nodes, result.records.test.displacement.shape
    (17, (17, 2001))
    >>> result.to_dict()["n_nodes"]
    17
    >>> print(result.summary().splitlines()[0])
    scenario: default
    """

    scenario: Scenario
    stages: tuple
    span: Any = None
    model: Any = None
    force: Any = None
    true_span: Any = None
    true_model: Any = None
    records: Records | None = None
    identification: Identification | None = None
    sensor_count: Any = None
    sensor_count_check: Any = None
    layouts: dict | None = None
    measured: MeasuredEstimate | None = None
    plan: Plan | None = None
    closed_loop: ClosedLoop | None = None
    severity: Severity | None = None
    fatigue: Fatigue | None = None
    failure: StageFailure | None = None
    elapsed: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """True when every stage asked for finished."""
        return self.failure is None

    @property
    def sensors(self) -> tuple:
        """The chosen sensors' node indices (empty before identification)."""
        if self.identification is None:
            return ()
        return tuple(int(i) for i in self.identification.design.sensors)

    def to_dict(self) -> dict:
        """The headline numbers as plain JSON types, one unit per quantity, units in the keys
        (:meth:`to_json` writes them as text, :meth:`summary` as lines).

        A key ending in ``_m`` is metres, ``_s`` seconds, ``_hz`` Hz, ``_m_s`` m/s,
        ``_percent`` per cent, ``_microstrain`` 1e-6; the ``units`` entry lists them.

        Returns
        -------
        dict

        Examples
        --------
        See :class:`ScenarioResult`.
        """
        from .summary_json import result_json

        return result_json(self)

    def summary(self) -> str:
        """The headline numbers of :meth:`to_dict`, one ``key: value`` line each (the scalars).

        Returns
        -------
        str

        Examples
        --------
        See :class:`ScenarioResult`.
        """
        return summary_of(self.to_dict())

    def sections(self) -> list:
        """The report's sections (title, intro, rows, figures to draw), in words and units.

        Returns
        -------
        list of dict

        Examples
        --------
        >>> from powerline_control.scenario import load_scenario
        >>> from powerline_control.scenario.pipeline import run_scenario
        >>> run_scenario(load_scenario(text="[model]\\nn_elements = 12"),
        ...              stages=("model",)).sections()[0]["title"]
        'Span and model'
        """
        from .summary import result_sections

        return result_sections(self)

    def verdict(self):
        """The report's first screen: the span, what was asked, the headline numbers with their
        one-line verdicts and sections, and the caveats that change a decision.

        Returns
        -------
        Verdict
            See :func:`~.summary_verdict.result_verdict`.

        Examples
        --------
        >>> from powerline_control.scenario import load_scenario
        >>> from powerline_control.scenario.pipeline import run_scenario
        >>> run_scenario(load_scenario(text="[model]\\nn_elements = 12"),
        ...              stages=("model",)).verdict().span
        '3.66 m paper lab (Table 1) span, tension 395 N, pinned / pinned supports'
        """
        from .summary_verdict import result_verdict

        return result_verdict(self)

    def report(self, path: str | Path, *, version: str | None = None) -> Path:
        """Write the self-contained HTML report of this result: its verdict first
        (:meth:`verdict`), then a section per stage.

        Parameters
        ----------
        path : str or Path
            The HTML file (its folder must exist).
        version : str or None
            Package version shown (default: this package's).

        Returns
        -------
        Path

        Raises
        ------
        InputError
            ``path`` is not a file path, is a folder, or its folder does not exist;
            ``version`` is not a string.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from powerline_control.scenario import load_scenario
        >>> from powerline_control.scenario.pipeline import run_scenario
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> result = run_scenario(load_scenario(text="[model]\\nn_elements = 12"),
        ...                       stages=("model",))
        >>> result.report(folder / "r.html").name
        'r.html'
        """
        from .summary import write_result_report

        # checked before the report's figures are drawn (seconds of work)
        path = check_write_path(path)
        if version is not None and not isinstance(version, str):
            raise InputError(f"The 'version' parameter must be a str (the version shown) or "
                             f"None. Got {version!r:.60} of type {type(version).__name__}.")
        return write_result_report(self, path, version=version)
