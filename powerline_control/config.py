"""Scenario files: a TOML description of one study (span, model, load, data, estimation, robot).

A scenario is a frozen :class:`Scenario` of small frozen sections. Every key has a default, so a
file names only what differs from the built-in default (the paper's lab span forced near its
third resonance). Unknown sections or keys are errors, never silently ignored: a typo in a file a
user saved must not change the study without telling them.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ._validation import check_choice, check_int, check_real
from .errors import InputError
from .excitation import AeolianForce, HarmonicForce, RandomForce
from .fem import LineModel, ModalDamping
from .line import Span, conductors

__all__ = ["Scenario", "load_scenario", "scenario_to_toml", "default_scenario"]


@dataclass(frozen=True)
class SpanConfig:
    """Which span: ``preset = "paper_lab"`` or a conductor preset with length and tension."""

    preset: str = "paper_lab"
    conductor: str = "drake"
    length: float = 300.0
    rts_fraction: float = 0.20

    def build(self) -> Span:
        """The :class:`Span` this section describes."""
        if self.preset == "paper_lab":
            return Span.paper_lab()
        if self.preset == "conductor":
            return Span.at_rts_fraction(self.length, conductors[self.conductor], self.rts_fraction)
        raise InputError(f"span.preset must be 'paper_lab' or 'conductor'. Got {self.preset!r}.")


@dataclass(frozen=True)
class ModelConfig:
    """Finite-element model: elements, supports and a modal damping ratio."""

    n_elements: int = 100
    bc: str = "pinned"
    damping_ratio: float = 0.0

    def build(self, span: Span) -> LineModel:
        """The :class:`LineModel` of ``span``."""
        ratio = check_real("model.damping_ratio", self.damping_ratio, low=0.0, low_inclusive=True,
                           high=1.0, high_inclusive=False)
        return LineModel(span, n_elements=self.n_elements, bc=self.bc,
                         damping=ModalDamping(ratio) if ratio > 0 else None)


@dataclass(frozen=True)
class ForcingConfig:
    """The load: ``kind`` is "harmonic", "aeolian" or "random"."""

    kind: str = "harmonic"
    amplitude: float = 1.0
    frequency: float = 24.0
    position: float = 0.5
    wind_speed: float = 3.0
    bandwidth: float = 100.0
    seed: int = 0

    def build(self):
        """The load object this section describes."""
        kind = check_choice("forcing.kind", self.kind, ("harmonic", "aeolian", "random"))
        if kind == "harmonic":
            return HarmonicForce(self.amplitude, self.frequency, self.position)
        if kind == "aeolian":
            return AeolianForce(wind_speed=self.wind_speed)
        return RandomForce(self.amplitude, self.position, self.bandwidth, self.seed)


@dataclass(frozen=True)
class SimulationConfig:
    """Data: duration, sample interval, sensor noise (fraction of RMS displacement), seed."""

    duration: float = 10.0
    dt: float = 1e-3
    noise_fraction: float = 0.01
    seed: int = 0


@dataclass(frozen=True)
class IdentificationConfig:
    """DMD: time delays and Tikhonov alpha ("auto" chooses by held-out prediction error)."""

    delays: int = 2
    alpha: float | str = "auto"
    rank: int | None = None


@dataclass(frozen=True)
class EstimationConfig:
    """Kalman filter: the sensor nodes, or how many to choose optimally."""

    sensors: tuple[int, ...] | None = None
    n_sensors: int = 3


@dataclass(frozen=True)
class RobotConfig:
    """The damping robot: where it starts (m), its masses (kg), absorber damping and limits.

    The absorber is tuned to the natural frequency nearest the load frequency. ``closed_loop``
    is the simulated time of the closed-loop run (s, calibration included; 0 skips it).
    """

    start: float = 1.2
    body_mass: float = 0.02
    suspended_mass: float = 0.05
    damping_ratio: float = 0.1
    v_max: float = 0.5
    a_max: float = 1.0
    closed_loop: float = 6.0


@dataclass(frozen=True)
class Scenario:
    """One study, as read from a TOML file (see :func:`load_scenario`).

    Attributes
    ----------
    span, model, forcing, simulation, identification, estimation, robot
        The sections of the file, each a frozen dataclass with defaults.

    Examples
    --------
    >>> scenario = default_scenario()
    >>> scenario.model.n_elements, scenario.span.preset
    (100, 'paper_lab')
    """

    span: SpanConfig = field(default_factory=SpanConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    forcing: ForcingConfig = field(default_factory=ForcingConfig)
    simulation: SimulationConfig = field(default_factory=SimulationConfig)
    identification: IdentificationConfig = field(default_factory=IdentificationConfig)
    estimation: EstimationConfig = field(default_factory=EstimationConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)


def default_scenario() -> Scenario:
    """The built-in scenario: the paper's lab span, 100 elements, forced at 24 Hz (near mode 3).

    The robot starts at 1.2 m, next to a node of mode 3 (L/3 = 1.22 m): the worst place to damp it.

    Examples
    --------
    >>> default_scenario().forcing.frequency
    24.0
    """
    return Scenario()


def _section(cls, name: str, table: object):
    if not isinstance(table, dict):
        raise InputError(f"[{name}] must be a table of keys. Got {table!r}.")
    allowed = {f.name: f for f in dataclasses.fields(cls)}
    unknown = set(table) - set(allowed)
    if unknown:
        raise InputError(f"Unknown key(s) {sorted(unknown)} in [{name}]; allowed keys are "
                         f"{sorted(allowed)}.")
    values = {}
    for key, value in table.items():
        default = allowed[key].default
        label = f"{name}.{key}"
        if key == "sensors":
            if not isinstance(value, list):
                raise InputError(f"{label} must be a list of node indices. Got {value!r}.")
            value = tuple(check_int(label, v, low=0) for v in value)
        elif key == "alpha":
            # "auto" or a number (the paper's absolute alpha, eq. 14).
            value = check_choice(label, value, ("auto",)) if isinstance(value, str) \
                else check_real(label, value, low=0.0, low_inclusive=True)
        elif isinstance(default, bool) or isinstance(default, str):
            if not isinstance(value, type(default)):
                raise InputError(f"{label} must be a {type(default).__name__}. Got {value!r}.")
        elif isinstance(default, int) or key == "rank":
            value = check_int(label, value, low=1 if key in ("n_elements", "rank", "delays",
                                                             "n_sensors") else 0)
        else:
            value = check_real(label, value)
        values[key] = value
    return cls(**values)


_SECTIONS = {f.name: f.default_factory for f in dataclasses.fields(Scenario)}


def load_scenario(path: str | Path | None = None, *, text: str | None = None) -> Scenario:
    """Read a scenario from a TOML file (or from ``text``); missing keys take their defaults.

    Parameters
    ----------
    path : str or Path or None
        File to read.
    text : str or None
        TOML text instead of a file.

    Returns
    -------
    Scenario

    Raises
    ------
    InputError
        On a missing or unreadable file, invalid TOML, unknown sections or keys, or bad values.

    Examples
    --------
    >>> load_scenario(text="[model]\\nn_elements = 20").model.n_elements
    20
    """
    if text is None:
        if path is None:
            return default_scenario()
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise InputError(f"Cannot read the scenario file {str(path)!r}: {exc}") from exc
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"The scenario is not valid TOML: {exc}") from exc
    unknown = set(data) - set(_SECTIONS)
    if unknown:
        raise InputError(f"Unknown section(s) {sorted(unknown)}; allowed sections are "
                         f"{sorted(_SECTIONS)}.")
    return Scenario(**{name: _section(type(factory()), name, data[name])
                       for name, factory in _SECTIONS.items() if name in data})


def _toml_value(value: object) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)


def scenario_to_toml(scenario: Scenario) -> str:
    """Write a scenario as TOML text that :func:`load_scenario` reads back to an equal scenario.

    Parameters
    ----------
    scenario : Scenario
        The scenario to write.

    Returns
    -------
    str

    Examples
    --------
    >>> text = scenario_to_toml(default_scenario())
    >>> load_scenario(text=text) == default_scenario()
    True
    """
    lines = ["# powerline_control scenario (SI units; positions in m from the left support)"]
    for name in _SECTIONS:
        lines.append(f"\n[{name}]")
        for key, value in dataclasses.asdict(getattr(scenario, name)).items():
            if value is None:
                lines.append(f"# {key} = (not set)")
            else:
                lines.append(f"{key} = {_toml_value(value)}")
    return "\n".join(lines) + "\n"
