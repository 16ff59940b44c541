"""Scenario files: a TOML description of one study (span, model, the line's truth, load, data,
estimation, robot).

A scenario is a frozen :class:`Scenario` of small frozen sections. Every key has a default, so a
file names only what differs from the defaults (the paper's lab span forced near its third
resonance, the line exactly as the file names it; the built-in scenario, :func:`default_scenario`,
adds a line 3 % slacker than Table 1). One schema (the metadata on each section's fields: unit,
meaning, allowed values, and when a key applies) drives three things: validation, the commented
TOML template of ``powerline-control scenario`` and the reference page ``docs/scenarios.md``
(:func:`~powerline_control.scenario.template.scenario_reference`; both writers live in
``template.py``).

The whole file is validated before anything is computed: types, ranges, positions on the span,
sensors on the span and off its fixed supports, and keys that conflict with the chosen preset or
load kind; every problem of the file is reported at once, in one message that names the file
and, for each problem, the dotted TOML key (``robot.start``), the value and what
is allowed. Unknown sections or keys are errors, never silently ignored: a typo in a file a user
saved must not change the study without telling them.

This module imports only the standard library at import time (the command's ``--help`` must stay
fast); building the physical objects imports the package's numerical modules.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass, field

from ..errors import InputError
from ._schema import _key

__all__ = ["Scenario", "TruthConfig", "default_scenario", "check_severity_inputs",
           "closed_loop_timing"]

#: Largest number of samples a scenario may ask ``simulate`` for (duration / dt): beyond it the
#: snapshot matrices of even a small model leave a laptop's memory.
MAX_SAMPLES = 2_000_000
#: Largest element count a scenario may ask for (dense sensor and estimator work is O(n^2)).
MAX_ELEMENTS = 20_000


@dataclass(frozen=True)
class ScenarioInfo:
    """Name and one-line description of the scenario (shown in the report)."""

    name: str = _key("default", "", "Short name of the scenario, shown in the report.")
    description: str = _key(
        "The paper's 3.66 m lab span, forced near its third resonance.", "",
        "One sentence saying what the scenario studies.")


@dataclass(frozen=True)
class SpanConfig:
    """The nominal span, what the engineer knows: `preset = "paper_lab"` or a conductor preset
    with length and tension ([truth] says how the line simulated differs)."""

    preset: str = _key(
        "paper_lab", "", "The paper's lab span (Table 1: 3.66 m, 395 N) or a conductor preset.",
        choices=("paper_lab", "conductor"))
    conductor: str = _key(
        "drake", "", "Conductor from the catalogue (data/conductors.toml).",
        when=("preset", ("conductor",)), allowed="a name in powerline_control.conductors")
    length: float = _key(300.0, "m", "Span length between supports.", low=0.0, high=5000.0,
                         when=("preset", ("conductor",)))
    rts_fraction: float = _key(
        0.20, "", "Everyday tension as a fraction of the conductor's rated tensile strength.",
        low=0.0, high=0.6, when=("preset", ("conductor",)))
    tension: float | None = _key(
        None, "N", "Tension, instead of span.rts_fraction (unset: from rts_fraction).",
        kind="real", low=0.0, when=("preset", ("conductor",)),
        allowed="a real number > 0 N, below the conductor's rated strength")

    def build(self):
        """The :class:`~powerline_control.line.Span` this section describes."""
        from ..line import Span, conductors

        if self.preset == "paper_lab":
            return Span.paper_lab()
        if self.tension is not None:
            return Span(length=self.length, tension=self.tension,
                        conductor=conductors[self.conductor])
        return Span.at_rts_fraction(self.length, conductors[self.conductor], self.rts_fraction)


@dataclass(frozen=True)
class ModelConfig:
    """Finite-element model: elements, supports and a modal damping ratio."""

    n_elements: int | str = _key(
        100, "", "Finite elements along the span, or \"auto\" for the mesh the physics chooses "
        "(resolves the aeolian band, graded toward clamped supports).", kind="n_elements",
        low=2, high=MAX_ELEMENTS, allowed=f'an integer 2..{MAX_ELEMENTS} or "auto"')
    bc: str = _key("pinned", "", "Supports at both ends.", choices=("pinned", "clamped"))
    damping_ratio: float = _key(0.0, "", "Modal damping ratio of the line (every mode).",
                                low=0.0, high=1.0, low_inclusive=True, high_inclusive=False)

    def damping(self, ratio: float | None = None):
        """The line's damping: ModalDamping of ``ratio`` (default ``damping_ratio``), None at 0."""
        from ..fem import ModalDamping

        ratio = self.damping_ratio if ratio is None else ratio
        return ModalDamping(ratio) if ratio > 0 else None

    def build(self, span):
        """The :class:`~powerline_control.fem.LineModel` of ``span``."""
        from ..fem import LineModel

        damping = self.damping()
        if self.n_elements == "auto":
            return LineModel(span, n_elements=None, bc=self.bc, damping=damping)
        return LineModel(span, n_elements=self.n_elements, bc=self.bc, damping=damping)


@dataclass(frozen=True)
class ForcingConfig:
    """The load: `kind` is "harmonic", "aeolian" or "random"."""

    kind: str = _key("harmonic", "", "Point harmonic force, aeolian vortex shedding (distributed, "
                     "Strouhal lock-in) or a band-limited random point force.",
                     choices=("harmonic", "aeolian", "random"))
    amplitude: float = _key(1.0, "N", "Force amplitude (harmonic) or standard deviation (random).",
                            low=0.0, high=1e6, when=("kind", ("harmonic", "random")))
    frequency: float = _key(24.0, "Hz", "Frequency of the harmonic force.", low=0.0, high=1e4,
                            when=("kind", ("harmonic",)))
    position: float = _key(0.5, "m", "Where the point force acts, from the left support.",
                           kind="real", when=("kind", ("harmonic", "random")),
                           allowed="0 < position < span length")
    wind_speed: float = _key(3.0, "m/s", "Wind speed of the aeolian load (shedding at "
                             "f = 0.185 V / d).", low=0.0, high=30.0, when=("kind", ("aeolian",)))
    lift_coefficient: float = _key(
        0.3, "", "Fluctuating lift coefficient C_L of the simulated aeolian load: a lift of "
        "0.5 rho V^2 d C_L per metre, fixed in amplitude (0.2-0.4 for a cylinder at aeolian "
        "Reynolds numbers: Blevins, Flow-Induced Vibration, 2nd ed., 1990, ch. 3). The energy "
        "balance (severity, the closed loop in the self-limiting wind) reads its wind power "
        "curve instead.", low=0.0, high=5.0, when=("kind", ("aeolian",)))
    bandwidth: float = _key(100.0, "Hz", "Highest frequency of the random force.", low=0.0,
                            high=1e4, when=("kind", ("random",)))
    seed: int = _key(0, "", "Seed of the random force.", low=0, when=("kind", ("random",)))

    def build(self):
        """The load object this section describes."""
        from ..excitation import AeolianForce, HarmonicForce, RandomForce

        if self.kind == "harmonic":
            return HarmonicForce(self.amplitude, self.frequency, self.position)
        if self.kind == "aeolian":
            return AeolianForce(wind_speed=self.wind_speed,
                                lift_coefficient=self.lift_coefficient)
        return RandomForce(self.amplitude, self.position, self.bandwidth, self.seed)

    def load_frequency(self, span) -> float:
        """The frequency the load drives, Hz: what the robot's absorber is tuned to.

        The harmonic force's frequency, the Strouhal frequency of the wind for the aeolian load,
        and the centre of the band (bandwidth / 2) for the random force.
        """
        if self.kind == "harmonic":
            return self.frequency
        if self.kind == "aeolian":
            from ..excitation import strouhal_frequency

            return strouhal_frequency(self.wind_speed, span.conductor.diameter)
        return 0.5 * self.bandwidth

    def describe(self, span, wind: str = "fixed_lift") -> str:
        """The load in words, with units; ``wind``: the scenario's ``robot.wind`` (what an
        aeolian load does to the simulated line)."""
        if self.kind == "harmonic":
            return (f"harmonic point force of {self.amplitude:g} N at {self.frequency:g} Hz, "
                    f"applied at x = {self.position:g} m")
        if self.kind == "aeolian" and wind == "self_limiting":
            return (f"aeolian vortex shedding in a {self.wind_speed:g} m/s wind, self-limiting: "
                    "the [severity] power curve's wind power at the locked mode's amplitude "
                    "against the conductor's self-damping, in the mode nearest the Strouhal "
                    f"frequency {self.load_frequency(span):.3g} Hz (St = 0.185, d = "
                    f"{1e3 * span.conductor.diameter:g} mm)")
        if self.kind == "aeolian":
            return (f"aeolian vortex shedding in a {self.wind_speed:g} m/s wind: a lift force "
                    f"distributed along the whole span at the Strouhal frequency "
                    f"{self.load_frequency(span):.3g} Hz (St = 0.185, d = "
                    f"{1e3 * span.conductor.diameter:g} mm, C_L = {self.lift_coefficient:g})")
        return (f"random point force (Gaussian, std {self.amplitude:g} N, band 0-"
                f"{self.bandwidth:g} Hz, seed {self.seed}) at x = {self.position:g} m")


@dataclass(frozen=True)
class SimulationConfig:
    """Data: duration, sample interval, sensor noise (fraction of RMS displacement), seed."""

    duration: float = _key(10.0, "s", "Simulated time (the first 60 % identifies the model, "
                           "the rest tests the estimator).", low=0.0, high=3600.0)
    dt: float = _key(1e-3, "s", "Sample interval.", low=0.0, high=1.0)
    noise_fraction: float = _key(0.01, "", "Sensor noise standard deviation as a fraction of the "
                                 "RMS displacement.", low=0.0, high=1.0, low_inclusive=True,
                                 high_inclusive=False)
    seed: int = _key(0, "", "Seed of the sensor noise.", low=0)


@dataclass(frozen=True)
class IdentificationConfig:
    """The estimator's identification: delays, alpha and rank (unset: the recipe chooses), and
    the broadband shaker of the identification run."""

    delays: int | None = _key(
        None, "", "Snapshots stacked per model state (time-delay embedding); unset: the "
        "package's recipe chooses.", kind="int", low=1, high=50)
    alpha: float | str = _key(
        "auto", "", "Tikhonov regularisation as a fraction of the largest squared singular "
        "value of the training data, or \"auto\" to choose it on held-out data.", kind="alpha",
        low=0.0, low_inclusive=True, high=1.0, allowed='"auto" or a real number in [0, 1]')
    rank: int | None = _key(None, "", "Rank of the identified model (the filter's state size); "
                            "unset: the package's recipe chooses.", kind="int", low=1, high=5000)
    shaker: float = _key(
        0.1, "N", "Standard deviation of a broadband shaker force, at 31 % of the span, added to "
        "an identification run (the scenario's load plus the shaker, as long as the training "
        "part) that trains the estimator: a harmonic record alone is not persistently exciting. "
        "0: train on the first 60 % of the scenario's own record.", low=0.0, low_inclusive=True,
        high=1e6)
    shaker_bandwidth: float = _key(100.0, "Hz", "Highest frequency of the shaker force.",
                                   low=0.0, high=1e4)


@dataclass(frozen=True)
class EstimationConfig:
    """Kalman filter: the sensors (node indices or positions), or how many to choose optimally."""

    sensors: tuple[int, ...] | None = _key(
        None, "", "Measured node indices (0 = left support); unset: chosen optimally.",
        kind="int_list", low=0, allowed="node indices inside the span, off the fixed supports")
    sensor_positions: tuple[float, ...] | None = _key(
        None, "m", "Measured positions (the nearest node is used); unset: chosen optimally.",
        kind="real_list", allowed="0 < x < span length")
    n_sensors: int = _key(3, "", "How many sensors to choose optimally (Kalman criterion).",
                          low=1, high=50)


@dataclass(frozen=True)
class RobotConfig:
    """The damping robot: where it starts, its masses, absorber damping and limits.

    The absorber is tuned to the line's mode nearest the load's frequency (see
    :meth:`ForcingConfig.load_frequency`): by Den Hartog's rule, or with the given
    ``damping_ratio`` at the Den Hartog frequency.
    ``closed_loop`` is the simulated time of the closed-loop run (calibration included; 0 skips
    it).
    """

    start: float = _key(1.2, "m", "Where the robot starts (and stays parked in the comparison).",
                        kind="real", allowed="0 < start < span length")
    body_mass: float = _key(0.02, "kg", "Mass of the robot's body, rigid on the line.",
                            low=0.0, low_inclusive=True, high=1000.0)
    suspended_mass: float = _key(0.05, "kg", "Mass of the tuned absorber.", low=0.0, high=1000.0)
    damping_ratio: float = _key(
        0.0, "", "Damping ratio of the absorber; 0 takes Den Hartog's optimum (frequency and "
        "damping) for the line's mode nearest the load; > 0: this ratio, c / (2 m omega_a), at "
        "Den Hartog's frequency.", low=0.0, low_inclusive=True, high=1.0,
        high_inclusive=False)
    v_max: float = _key(0.5, "m/s", "Largest robot speed.", low=0.0, high=20.0)
    a_max: float = _key(1.0, "m/s^2", "Largest robot acceleration.", low=0.0, high=100.0)
    closed_loop: float = _key(12.0, "s", "Simulated time of the closed loop (0 skips it).",
                              low=0.0, low_inclusive=True, high=600.0,
                              allowed="0 (no closed loop), or up to 600 s with a calibration "
                                      "(a third, at most 2 s) long enough for the estimator")
    estimator: str = _key(
        "robot_input", "", "The closed loop's estimator: the bare line's modes with the robot's "
        "measured force as an input at its position, so that it stays consistent while the "
        "robot moves, or the recipe's, identified with the robot parked at its start "
        "(run_closed_loop's estimator).",
        choices=("recipe", "robot_input"))
    wind: str = _key(
        "fixed_lift", "", "What the aeolian wind does to the closed loop's simulated line: a "
        "lift of fixed amplitude on the line's own damping, or the self-limiting wind of the "
        "energy balance (the severity section's power curve at the locked mode's current "
        "amplitude, its self-damping law on every mode; the line starts at the balance's "
        "amplitude) (run_closed_loop's wind). The self-limiting wind also makes the records "
        "the estimator is identified on (severity.simulate_self_limiting), which then refuse a "
        "shaker (identification.shaker = 0).",
        choices=("fixed_lift", "self_limiting"))


#: The names of severity.WIND_POWER_CURVES and of the SELF_DAMPING_LAWS that carry a tension
#: exponent (the schema imports no numerical module; a test keeps these equal to the tables).
WIND_CURVE_NAMES = ("cigre", "farquharson", "carroll", "rawlins58", "bate", "diana", "pon")
SELF_DAMPING_NAMES = ("noiseux1991", "tompkins", "claren", "seppa", "kraus", "mocks", "pdm")


@dataclass(frozen=True)
class SeverityConfig:
    """Aeolian severity by the energy balance method (a report section when enabled)."""

    enabled: bool = _key(False, "", "Add the energy-balance severity study to the run and report.")
    wind_speeds: tuple[float, ...] = _key(
        (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0), "m/s", "Wind speeds of the severity study.",
        kind="real_list", low=0.0, high=30.0, when=("enabled", (True,)))
    outer_strand_diameter: float | None = _key(
        None, "m", "Diameter of one outer strand, for the clamp stress (Poffenberger-Swart); "
        "unset: the conductor preset's stranding (the lab span: 3.5 mm, the 7 x 3.50 mm "
        "strands of AAC 2/0, the conductor Table 1 matches).", kind="real", low=0.0, high=0.05,
        when=("enabled", (True,)))
    outer_strand_modulus: float = _key(
        68.9e9, "Pa", "Young's modulus of the outer strands (aluminium: 68.9 GPa).", low=0.0,
        high=1e12, when=("enabled", (True,)))
    clamp_distance: float = _key(
        0.089, "m", "Where the bending amplitude Y_b is taken: this far from the last point of "
        "contact at the clamp (IEEE: 89 mm).", low=0.0, high=10.0,
        when=("enabled", (True,)))
    rated_strength: float | None = _key(
        None, "N", "Rated tensile strength for the self-damping normalisation (Lilien: k = "
        "D / sqrt(m RTS)); unset: the conductor's (the lab span: the catalogue value of AAC "
        "2/0 Oxlip, the conductor Table 1 matches, about 11 kN).", kind="real", low=0.0,
        high=1e7, when=("enabled", (True,)))
    ei: float | None = _key(
        None, "N m^2", "Bending stiffness EI_min of the stranded conductor for the severity "
        "study (loop lengths and clamp stress); unset: the conductor's own EI.", kind="real",
        low=0.0, high=1e6, when=("enabled", (True,)))
    wind_curve: str = _key(
        "cigre", "", "Wind power curve P_w = f^3 D^4 F(Y/D) of the energy balance and of its "
        "time-domain check: 'cigre' (the CIGRE cubic, Foti & Martinelli 2018 eqs. 4-5) or a "
        "digitised curve of rte-france/pallas-dohl's table (from the EPRI Orange Book figure).",
        choices=WIND_CURVE_NAMES, when=("enabled", (True,)))
    self_damping: str = _key(
        "noiseux1991", "", "Conductor self-damping law P_c = k Y^l f^m / T^n (the exponent sets "
        "of rte-france/pallas-dohl's damping_power_data.yaml; k by the Lilien normalisation "
        "D / sqrt(m RTS)).", choices=SELF_DAMPING_NAMES, when=("enabled", (True,)))
    time_domain: bool = _key(
        True, "", "Check the energy balance at the [forcing] wind speed in the time domain with "
        "the same two powers (severity.simulate_aeolian), without dampers and with the robot "
        "parked at the antinode, and judge the closed loop's final position in the same "
        "self-limiting wind (aeolian forcing only; skipped, with the reason, where that wind "
        "cannot hold the balance).", when=("enabled", (True,)))
    wind_record: str | None = _key(
        None, "", "A wind record, a CSV file with columns time, wind_speed, direction, "
        "temperature (and optionally turbulence_intensity): adds the fatigue stage to run and "
        "severity (damage per year and life with no damper, a fixed damper and the robot over "
        "the record). A relative path is read from the scenario file's folder; the severity "
        "verb's --wind-record option replaces it.", kind="str",
        allowed="the path of a CSV file")


@dataclass(frozen=True)
class TruthConfig:
    """The line as it really is, where it differs from the nominal [span] (every key optional).

    The ``[span]`` section is the nominal: what the engineer knows. ``temperature`` (the true
    tension from the change of state) and ``tension_factor`` are alternatives; ``ei_factor``,
    ``mass_factor`` and ``damping_ratio`` change the true conductor and its damping.

    Examples
    --------
    >>> TruthConfig().tension_factor is None, TruthConfig().ei_factor
    (True, 1.0)
    """

    temperature: float | None = _key(
        None, "degC", "Conductor temperature of the day simulated: the true tension is the "
        "nominal span's change of state from truth.stringing_temperature (the parabolic "
        "change-of-state equation); unset: the nominal tension, or truth.tension_factor. Needs a "
        "conductor preset (area, elastic modulus, thermal expansion).", kind="real", low=-40.0,
        low_inclusive=True, high=100.0)
    stringing_temperature: float = _key(
        15.0, "degC", "Conductor temperature at which the line has the nominal [span] tension "
        "(when it was strung; 15 degC: the everyday temperature of CIGRE TB 273).",
        low=-40.0, low_inclusive=True, high=100.0, needs="temperature")
    tension_factor: float | None = _key(
        None, "", "True tension over the nominal [span] tension, instead of truth.temperature "
        "(unset: 1, or from truth.temperature).", kind="real", low=0.5, low_inclusive=True,
        high=1.5)
    ei_factor: float = _key(
        1.0, "", "True bending stiffness EI over the catalogue's (a stranded conductor's EI lies "
        "between its strands' and the solid section's).", low=0.2, low_inclusive=True, high=5.0)
    mass_factor: float = _key(
        1.0, "", "True mass per metre over the catalogue's.", low=0.8, low_inclusive=True,
        high=1.2)
    damping_ratio: float | None = _key(
        None, "", "Modal damping ratio of the true line (every mode); unset: model.damping_ratio.",
        kind="real", low=0.0, low_inclusive=True, high=1.0, high_inclusive=False)

    @property
    def differs(self) -> bool:
        """Whether any key is set: the line simulated may differ from the nominal."""
        return self != TruthConfig()


@dataclass(frozen=True)
class Scenario:
    """One study, as read from a TOML file (see :func:`load_scenario`).

    Attributes
    ----------
    scenario, span, model, truth, forcing, simulation, identification, estimation, robot, severity
        The sections of the file, each a frozen dataclass with defaults (``span`` and ``model``
        are the nominal line, what the engineer knows; ``truth`` how the line simulated differs
        from it, :mod:`~powerline_control.scenario.truth`).

    Examples
    --------
    >>> scenario = default_scenario()
    >>> scenario.model.n_elements, scenario.span.preset
    (100, 'paper_lab')
    """

    scenario: ScenarioInfo = field(default_factory=ScenarioInfo)
    span: SpanConfig = field(default_factory=SpanConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    truth: TruthConfig = field(default_factory=TruthConfig)
    forcing: ForcingConfig = field(default_factory=ForcingConfig)
    simulation: SimulationConfig = field(default_factory=SimulationConfig)
    identification: IdentificationConfig = field(default_factory=IdentificationConfig)
    estimation: EstimationConfig = field(default_factory=EstimationConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    severity: SeverityConfig = field(default_factory=SeverityConfig)

    def __post_init__(self):
        # a section given as text, a number or None would pass until a stage reads it
        for section in dataclasses.fields(self):
            value, kind = getattr(self, section.name), section.default_factory
            if not isinstance(value, kind):
                raise InputError(
                    f"The {section.name!r} parameter must be a {kind.__name__} (the "
                    f"[{section.name}] section of a scenario file). Got {_repr(value)} of type "
                    f"{type(value).__name__}; build one with {kind.__name__}(...) or read a "
                    "file with load_scenario.")

    @property
    def name(self) -> str:
        """The scenario's name."""
        return self.scenario.name

    def span_length(self) -> float:
        """Length of the span this scenario describes, m (no model is built)."""
        if self.span.preset == "paper_lab":
            from ..line import Span

            return Span.paper_lab().length
        return self.span.length


_SECTIONS = {f.name: f.default_factory for f in dataclasses.fields(Scenario)}


def default_scenario() -> Scenario:
    """The built-in scenario: the paper's lab span, 100 elements, forced at 24 Hz (near mode 3).

    The robot starts at 1.2 m, next to a node of mode 3 (L/3 = 1.22 m): the worst place to damp it.
    The line simulated is not quite the one Table 1 gives: its tension is 3 % low (383 N, a lab
    span's turnbuckle set by hand), so the controller, told 395 N, calibrates the line from the
    sensors' records before it trusts its predictions. A file's sections default to
    ``Scenario()``, whose line is exactly the nominal one; a file without ``[truth]`` simulates the
    span it names.

    Examples
    --------
    >>> default_scenario().forcing.frequency
    24.0
    >>> default_scenario().truth.tension_factor
    0.97
    """
    return Scenario(truth=TruthConfig(tension_factor=0.97))


# ----------------------------------------------------------------------------- validation

def _repr(value: object) -> str:
    text = repr(value) if not isinstance(value, str) else f'"{value}"'
    return text if len(text) <= 60 else text[:57] + "..."


def _range_text(meta: dict) -> str:
    if meta["allowed"]:
        return meta["allowed"]
    if meta["choices"]:
        return "one of " + ", ".join(_repr(c) for c in meta["choices"])
    kind = {"real": "a real number", "int": "an integer", "bool": "true or false",
            "str": "a string", "int_list": "a list of integers",
            "real_list": "a list of real numbers"}.get(meta["kind"], meta["kind"])
    bounds = []
    if meta["low"] is not None:
        bounds.append((">= " if meta["low_inclusive"] or meta["kind"] in ("int", "int_list")
                       else "> ") + f"{meta['low']:g}")
    if meta["high"] is not None:
        bounds.append(("<= " if meta["high_inclusive"] or meta["kind"] in ("int", "int_list")
                       else "< ") + f"{meta['high']:g}")
    unit = f" {meta['unit']}" if meta["unit"] else ""
    return kind + (" " + " and ".join(bounds) + unit if bounds else "")


class _Invalid(Exception):
    """One key's value is refused (recorded by the checker; the key keeps its default)."""


class _Checker:
    """Validates one file's values and collects every problem, each naming the dotted key.

    ``fail`` records a problem and raises :class:`_Invalid` (the key being read is skipped and
    keeps its default, so the other checks still run); ``note`` records one without raising.
    :meth:`raise_if_any` raises one :class:`InputError` naming the file and every problem.
    """

    def __init__(self, source: str):
        self.source = source
        self.problems: list[str] = []

    def note(self, message: str) -> None:
        """Record a problem (a sentence naming the dotted key) and go on checking."""
        if message not in self.problems:
            self.problems.append(message)

    def refuse(self, key: str, value: object, allowed: str, why: str = "") -> None:
        """Record that ``key = value`` is not allowed (no exception)."""
        why = f" {why}" if why else ""
        self.note(f"{key} = {_repr(value)} is not allowed.{why} Allowed: {allowed}.")

    def fail(self, key: str, value: object, allowed: str, why: str = "") -> None:
        """Record that ``key = value`` is not allowed and stop reading that key."""
        self.refuse(key, value, allowed, why)
        raise _Invalid(key)

    def raise_if_any(self) -> None:
        """One InputError naming the file and every problem found (none: return)."""
        if not self.problems:
            return
        if len(self.problems) == 1:
            raise InputError(f"{self.source}: {self.problems[0]}")
        listed = " ".join(f"({i}) {p}" for i, p in enumerate(self.problems, 1))
        raise InputError(f"{self.source}: {len(self.problems)} problems: {listed}")

    def number(self, key: str, value: object, meta: dict, integer: bool) -> float | int:
        ok_type = (isinstance(value, numbers.Integral) if integer
                   else isinstance(value, numbers.Real)) and not isinstance(value, bool)
        if not ok_type:
            self.fail(key, value, _range_text(meta),
                      f"It must be {'an integer' if integer else 'a number'}, "
                      f"not {_toml_type(value)}.")
        if not integer and not math.isfinite(value):
            self.fail(key, value, _range_text(meta), "It must be finite.")
        low, high = meta["low"], meta["high"]
        low_ok = low is None or value > low or (value == low and (meta["low_inclusive"]
                                                                  or integer))
        high_ok = high is None or value < high or (value == high and (meta["high_inclusive"]
                                                                      or integer))
        if not (low_ok and high_ok):
            self.fail(key, value, _range_text(meta))
        return int(value) if integer else float(value)

    def value(self, key: str, value: object, meta: dict) -> object:
        kind = meta["kind"]
        if kind == "bool":
            if not isinstance(value, bool):
                self.fail(key, value, "true or false", f"It is {_toml_type(value)}.")
            return value
        if kind == "str":
            if not isinstance(value, str):
                self.fail(key, value, _range_text(meta), f"It is {_toml_type(value)}.")
            if meta["choices"] and value not in meta["choices"]:
                self.fail(key, value, _range_text(meta))
            return value
        if kind in ("int", "real"):
            return self.number(key, value, meta, integer=kind == "int")
        if kind == "n_elements":
            if isinstance(value, str):
                if value != "auto":
                    self.fail(key, value, _range_text(meta))
                return value
            return self.number(key, value, meta, integer=True)
        if kind == "alpha":
            if isinstance(value, str):
                if value != "auto":
                    self.fail(key, value, _range_text(meta))
                return value
            return self.number(key, value, meta, integer=False)
        # lists
        if not isinstance(value, list) or not value:
            self.fail(key, value, _range_text(meta), "It must be a non-empty list.")
        item_meta = dict(meta, allowed=None)
        items = tuple(self.number(f"{key}[{i}]", v, item_meta, integer=kind == "int_list")
                      for i, v in enumerate(value))
        if len(set(items)) != len(items):
            self.fail(key, value, "distinct values", "It repeats a value.")
        return items


def _toml_type(value: object) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, numbers.Integral):
        return "an integer"
    if isinstance(value, numbers.Real):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "a table"
    return type(value).__name__


def _read_section(check: _Checker, cls, name: str, table: object):
    if not isinstance(table, dict):
        check.note(f"[{name}] must be a table of keys. Got {_repr(table)}.")
        return cls()
    fields = {f.name: f for f in dataclasses.fields(cls)}
    values = {}
    for key, raw in table.items():
        if key not in fields:
            check.note(f"unknown key {name}.{key}. The keys of [{name}] are: "
                       f"{', '.join(fields)}.")
            continue
        try:
            values[key] = check.value(f"{name}.{key}", raw, fields[key].metadata)
        except _Invalid:
            continue
    # Keys that apply only to some values of another key (e.g. span.length with a preset), or
    # only when another key is set (truth.stringing_temperature needs truth.temperature).
    for key in list(values):
        needs = fields[key].metadata["needs"]
        if needs is not None and values.get(needs, fields[needs].default) is None:
            check.note(f"{name}.{key} applies only when {name}.{needs} is set. Remove "
                       f"{name}.{key} or set {name}.{needs}.")
            del values[key]
            continue
        when = fields[key].metadata["when"]
        if when is None:
            continue
        other, allowed_values = when
        current = values.get(other, fields[other].default)
        if current not in allowed_values:
            shown = " or ".join(_repr(v).lower() if isinstance(v, bool) else _repr(v)
                                for v in allowed_values)
            current_text = _repr(current).lower() if isinstance(current, bool) else _repr(current)
            check.note(
                f"{name}.{key} conflicts with {name}.{other} = {current_text}: "
                f"{name}.{key} applies only when {name}.{other} = {shown}. Remove {name}.{key} "
                f"or set {name}.{other} = {shown}.")
            del values[key]
    return cls(**values)


def _check_scenario(check: _Checker, scenario: Scenario, given: dict) -> None:
    """Cross-section checks that need the span: positions, sensors, sizes."""
    span = scenario.span
    if span.preset == "conductor":
        from ..line import conductors

        if span.conductor not in conductors:
            check.refuse("span.conductor", span.conductor,
                       "one of " + ", ".join(_repr(n) for n in conductors))
        if span.tension is not None:
            if "rts_fraction" in given.get("span", {}):
                check.note("span.tension conflicts with span.rts_fraction: "
                                 "give the tension in N or as a fraction of the rated strength, "
                                 "not both.")
            rated = conductors[span.conductor].rated_strength
            if span.tension >= rated:
                check.refuse("span.tension", span.tension,
                           f"a real number > 0 N and < {rated:g} N (the rated strength of "
                           f"{span.conductor})", "The conductor would break.")
    length = scenario.span_length()
    inside = f"0 < x < {length:g} m (the span length)"
    if scenario.forcing.kind != "aeolian" and not 0 < scenario.forcing.position < length:
        check.refuse("forcing.position", scenario.forcing.position, inside,
                   "The force must act on the span.")
    if not 0 < scenario.robot.start < length:
        check.refuse("robot.start", scenario.robot.start, inside, "The robot must be on the span.")
    est = scenario.estimation
    if est.sensors is not None and est.sensor_positions is not None:
        check.note("estimation.sensors conflicts with "
                         "estimation.sensor_positions: give node indices or positions, not both.")
    chosen = est.sensors if est.sensors is not None else est.sensor_positions
    if chosen is not None and "n_sensors" in given.get("estimation", {}):
        check.note("estimation.n_sensors conflicts with the sensors the "
                         "scenario lists: n_sensors is how many to choose when none are listed. "
                         "Remove one of them.")
    if est.sensors is not None:
        n_el = scenario.model.n_elements
        if n_el == "auto":
            check.note(
                f"estimation.sensors = {_repr(list(est.sensors))} names node "
                "indices, but model.n_elements = \"auto\" lets the physics choose the mesh, so "
                "node numbers are not known in advance. Use estimation.sensor_positions (m) or "
                "set model.n_elements.")
        for i, node in enumerate(est.sensors if n_el != "auto" else ()):
            if node > n_el:
                check.refuse(f"estimation.sensors[{i}]", node,
                           f"node indices 1..{n_el - 1} (model.n_elements = {n_el})",
                           "It is not on the span.")
            if node in (0, n_el):
                check.refuse(f"estimation.sensors[{i}]", node,
                           f"node indices 1..{n_el - 1} (model.n_elements = {n_el})",
                           "Node 0 and the last node sit on the supports, which never move: a "
                           "sensor there measures only noise.")
    if est.sensor_positions is not None:
        for i, x in enumerate(est.sensor_positions):
            if not 0 < x < length:
                check.refuse(f"estimation.sensor_positions[{i}]", x, inside,
                           "Sensors must be on the span, off its fixed supports.")
    sim = scenario.simulation
    n_samples = sim.duration / sim.dt
    if n_samples > MAX_SAMPLES:
        check.refuse("simulation.duration", sim.duration,
                   f"duration / dt <= {MAX_SAMPLES:.0e} samples",
                   f"With dt = {sim.dt:g} s that is {n_samples:.3g} samples; shorten the "
                   "duration or lengthen dt.")
    if n_samples < 50:
        check.refuse("simulation.duration", sim.duration,
                   "at least 50 samples (duration / dt >= 50)",
                   f"With dt = {sim.dt:g} s that is only {n_samples:.3g} samples.")
    if scenario.forcing.kind == "harmonic" and scenario.forcing.frequency >= 0.5 / sim.dt:
        check.refuse("forcing.frequency", scenario.forcing.frequency,
                   f"below the Nyquist frequency 1 / (2 dt) = {0.5 / sim.dt:g} Hz "
                   "(simulation.dt)")
    if scenario.robot.wind == "self_limiting" and scenario.forcing.kind != "aeolian":
        check.refuse("robot.wind", scenario.robot.wind, '"fixed_lift" with forcing.kind = '
                     f'{_repr(scenario.forcing.kind)}',
                     "The self-limiting wind is an aeolian load: set forcing.kind = \"aeolian\".")
    if scenario.robot.closed_loop > 0:
        _check_calibration_record(check, scenario)
    if scenario.robot.closed_loop > sim.duration * 10:
        check.refuse("robot.closed_loop", scenario.robot.closed_loop,
                   f"at most 10 x simulation.duration = {10 * sim.duration:g} s")

    n_el = scenario.model.n_elements
    if chosen is None and n_el != "auto" and est.n_sensors > n_el - 1:
        check.refuse("estimation.n_sensors", est.n_sensors,
                     f"at most {n_el - 1}, the interior nodes of model.n_elements = {n_el} "
                     "(the two end nodes sit on the supports)")
    _check_severity(check, scenario, given)


#: The closed loop's control period, s, and the longest calibration (robot parked, estimator
#: identified), s: a third of the run at most.
CONTROL_PERIOD = 0.05
MAX_CALIBRATION = 2.0


def closed_loop_timing(scenario: Scenario) -> tuple[float, float]:
    """(dt, calibration) of the closed loop, s.

    The calibration (robot parked, the estimator identified) is a third of the run, at most
    :data:`MAX_CALIBRATION`, in whole :data:`CONTROL_PERIOD` control periods.

    Parameters
    ----------
    scenario : Scenario
        Its ``simulation.dt`` and ``robot.closed_loop``.

    Returns
    -------
    (float, float)

    Examples
    --------
    >>> from powerline_control.scenario import load_scenario
    >>> closed_loop_timing(load_scenario(text="[robot]\\nclosed_loop = 12.0"))
    (0.001, 2.0)
    """
    dt = scenario.simulation.dt
    period = max(dt, round(CONTROL_PERIOD / dt) * dt)
    calibration = max(1, round(min(MAX_CALIBRATION, scenario.robot.closed_loop / 3) / period))
    return dt, round(calibration * period / dt) * dt


def _check_calibration_record(check: _Checker, scenario: Scenario) -> None:
    """Refuse a closed loop whose calibration (a third of it, at most 2 s) holds too few
    samples for the estimator's recipe."""
    from ..closed_loop.settings import calibration_samples
    from ..recipe.defaults import shortest_record

    needed = shortest_record()   # the closed loop identifies with the recipe's default delays

    def samples(closed_loop: float) -> int:   # the closed loop's calibration record
        robot = dataclasses.replace(scenario.robot, closed_loop=closed_loop)
        dt, calibration = closed_loop_timing(dataclasses.replace(scenario, robot=robot))
        return calibration_samples(calibration, dt)

    given = samples(scenario.robot.closed_loop)
    if given >= needed:
        return
    # the calibration is a third of the run up to MAX_CALIBRATION: longer runs add nothing
    longest = int(30 * MAX_CALIBRATION) + 1
    shortest = next((0.1 * k for k in range(1, longest + 1) if samples(0.1 * k) >= needed), None)
    if shortest is None:
        allowed = (f"0 (no closed loop): at simulation.dt = {scenario.simulation.dt:g} s even "
                   f"the longest calibration ({MAX_CALIBRATION:g} s) holds fewer than {needed} "
                   "samples; lower simulation.dt")
    else:
        allowed = f"0 (no closed loop) or at least {shortest:.1f} s"
    check.refuse("robot.closed_loop", scenario.robot.closed_loop, allowed,
                 f"A third of it (at most {MAX_CALIBRATION:g} s; here {given} samples) "
                 "calibrates the estimator with the robot parked, and the estimator's recipe "
                 f"needs at least {needed} samples.")


def _check_severity(check: _Checker, scenario: Scenario, given: dict) -> None:
    """Severity needs an outer-strand diameter and EI > 0: refuse, naming the key to add."""
    sev = scenario.severity
    if not sev.enabled:
        return
    if sev.outer_strand_diameter is None and scenario.span.preset == "conductor":
        from ..line import conductors

        if scenario.span.conductor in conductors and \
                conductors[scenario.span.conductor].outer_strand_diameter is None:
            check.note(f"severity.enabled = true needs the outer-strand diameter of conductor "
                       f"{scenario.span.conductor!r}, which its preset does not carry: add "
                       "severity.outer_strand_diameter (m).")
    if sev.ei is None and scenario.span.preset == "conductor":
        from ..line import conductors

        if conductors[scenario.span.conductor].ei <= 0:
            check.note("severity.enabled = true needs the conductor's bending stiffness for the "
                       f"clamp stress, and conductor {scenario.span.conductor!r} has EI = 0: "
                       "add severity.ei (N m^2).")
    if sev.outer_strand_diameter is not None:
        from ..line import Span, conductors

        diameter = (Span.paper_lab().conductor.diameter if scenario.span.preset == "paper_lab"
                    else conductors[scenario.span.conductor].diameter
                    if scenario.span.conductor in conductors else None)
        if diameter is not None and sev.outer_strand_diameter >= diameter:
            check.refuse("severity.outer_strand_diameter", sev.outer_strand_diameter,
                         f"below the conductor's diameter {1e3 * diameter:g} mm")




def check_severity_inputs(scenario: Scenario, source: str = "<scenario>") -> None:
    """Refuse a severity study this scenario cannot run, naming the key to add.

    ``load_scenario`` runs this check when ``severity.enabled``; the ``severity`` verb runs it
    for any scenario.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    source : str
        Its name for messages.

    Raises
    ------
    InputError
        When the outer-strand diameter or the bending stiffness is unknown.

    Examples
    --------
    >>> check_severity_inputs(default_scenario())   # the lab preset carries its strands
    """
    check = _Checker(source)
    _check_severity(check, dataclasses.replace(
        scenario, severity=dataclasses.replace(scenario.severity, enabled=True)), {})
    check.raise_if_any()
