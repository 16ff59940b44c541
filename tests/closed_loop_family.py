"""A seeded family of closed-loop scenarios nobody tuned for, and an independent judge of a run.

Used by ``tests/test_closed_loop_family.py`` and ``benchmarks/bench_closed_loop_family.py``; not
a test file itself.

Drawing and splitting
---------------------
``scenario(seed)`` is a pure function of the seed (``numpy.random.default_rng(seed)``). The
**split is the seed's parity**: even seeds are ``"tune"``, odd seeds ``"held_out"``
(``held_out_seeds(n)`` = 1, 3, 5, ...). The category cycles with ``seed // 2`` over
:data:`CATEGORIES`, so both splits cover every category equally, and the conductor of a real
span cycles with ``seed // 2`` over every preset of ``plc.conductors`` (5 presets against 7
categories: every conductor meets every real category within 35 seeds of a split).

Categories: the lab span (``Span.paper_lab()``, 100 elements) under a harmonic load on a mode
(0.99-1.01 f_n), between two modes, a wind change (mode a then mode b), or aeolian lock-in;
real spans (150-450 m at 15-25 % RTS, every preset) under aeolian lock-in, a harmonic point load
on or between modes, or an aeolian wind change (V_a -> V_b 15-35 % apart). Supports pinned or
clamped (random), line damping ``ModalDamping`` 0.2-0.5 % (lab) or log-uniform 0.05-0.5 % (real
spans, the realistic self-damping range: lighter lines ring for tens of seconds), sensors
chosen by the toolbox (``design_estimator`` on a 2 s training simulation of the bare line under
the first load plus a broadband shaker) or at random interior nodes (never a support node, nor
within 2 % of the span from one), the robot tuned with ``tune_damper`` to the mode nearest the
first load and starting at random, in 40 % of the runs within 3 % of a loop of a vibration node
of the first load's mode.

Real spans keep the excited mode number <= 110 (the plant's band and the scan grow with it: a
450 m Oxlip span at 1 m/s is mode 145); the wind speed is clipped to that, which puts some
Oxlip spans below 1 m/s. Their mesh is either the physics default (``n_elements=None``) or a
uniform mesh with 8 elements per loop at 1.3x the highest load frequency (always for Oxlip,
whose default mesh resolving 7 m/s at 10.5 mm would be 4000 elements on 450 m).

The judge
---------
``evaluate(scenario, result)`` does not use the closed loop's plant. The steady state with the
robot parked at p is a sparse direct solve of the full FE model with the robot attached,
``LineModel(span, n_elements, bc, mdr=replace(robot, position=p))`` (absorber = last free DOF):

    (K - w^2 M + i w (C_robot + C_line)) u = f

with f the load vector of the final load. Line damping: ``RayleighDamping`` gives
``C_line = a M_line + b K_line`` (the bare line's matrices: the robot's body is not damped by
the line). ``ModalDamping(zeta)`` is defined on the *bare* line's modes (as the closed loop's
plant defines it): ``C_line = M Phi diag(2 zeta_n omega_n) Phi^T M`` over the bare modes up to
3x the load frequency (every mode on the lab span), applied exactly through the Woodbury
identity on the sparse LU of the rest; the modes above get no damping, which changes their
quasi-static response by O(zeta^2).  Span RMS = sqrt(sum_j w_j |u_j|^2 / 2), trapezoid weights
over ``model.node_positions`` normalised by the length.

The best parked position is searched over the reach: the whole span on the lab span (4 points
per element), on real spans the positions p inside [body/2, L - body/2] with
``limits.rest_to_rest_time(|p - start|) <= 0.5 * (duration - calibration)`` (20 points per loop),
plus a refinement (21 points over +-1 grid step) around the grid minimum. Every load in the
family is one sine in time (the aeolian load is ``sin(k x) sin(w t)``), so the steady state is
exact; a non-harmonic final load would get the run's window RMS instead (``truth="window"``).
"""

from __future__ import annotations

import dataclasses
import math
import time
import traceback
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import powerline_control as plc
from powerline_control.excitation import DEFAULT_STROUHAL

CATEGORIES = (
    "lab/mode",
    "lab/between",
    "lab/wind-change",
    "lab/aeolian",
    "real/aeolian",
    "real/harmonic",
    "real/wind-change",
)
CONDUCTORS = tuple(sorted(plc.conductors))
LAB_ELEMENTS = 100
MAX_REAL_MODE = 110
# the reach: the policy's share of (duration - calibration) spent travelling (one home: its
# settings)
TRAVEL_FRACTION = plc.PolicySettings().travel_fraction


# ---------------------------------------------------------------------------------- scenarios
@dataclass(frozen=True)
class Scenario:
    """One closed-loop run to judge (everything ``run_closed_loop`` is given, plus labels)."""

    seed: int
    split: str                 # "tune" (even seed) or "held_out" (odd seed)
    category: str
    span: plc.Span
    bc: str
    damping: object
    force: object              # a load, or a schedule ((0.0, load_a), (t1, load_b))
    robot: plc.MDR
    limits: plc.RobotLimits
    sensors: tuple
    n_elements: int | None
    duration: float
    calibration: float
    dt: float
    sensor_layout: str         # "toolbox" or "random"
    description: str = ""
    nominal: plc.Span | None = None   # what the controller is told (None: the span itself)
    calibrate: bool = True            # the controller calibrates the nominal from its records

    @property
    def final_load(self):
        """The load acting at the end of the run."""
        return self.force[-1][1] if isinstance(self.force, tuple) else self.force

    @property
    def first_load(self):
        """The load acting at the start."""
        return self.force[0][1] if isinstance(self.force, tuple) else self.force

    def run_arguments(self) -> dict:
        """Keyword arguments of ``plc.run_closed_loop`` (the documented ones only)."""
        force = [tuple(item) for item in self.force] if isinstance(self.force, tuple) \
            else self.force
        told = {} if self.nominal is None else {"nominal": self.nominal,
                                                 "calibrate": self.calibrate}
        return dict(span=self.span, force=force, robot=self.robot, limits=self.limits,
                    sensors=list(self.sensors), n_elements=self.n_elements, bc=self.bc,
                    damping=self.damping, duration=self.duration,
                    calibration=self.calibration, dt=self.dt, seed=self.seed, **told)

    def rerun_hint(self) -> str:
        """How to rebuild this scenario."""
        return f"closed_loop_family.scenario({self.seed})  # {self.description}"


def split_of(seed: int) -> str:
    """'tune' for even seeds, 'held_out' for odd ones."""
    return "tune" if seed % 2 == 0 else "held_out"


def held_out_seeds(n: int, start: int = 0) -> list[int]:
    """The first ``n`` held-out seeds (odd), from the ``start``-th."""
    return [2 * (start + i) + 1 for i in range(n)]


def tune_seeds(n: int, start: int = 0) -> list[int]:
    """The first ``n`` tuning seeds (even), from the ``start``-th."""
    return [2 * (start + i) for i in range(n)]


def family(split: str = "held_out", n: int = 42) -> list[int]:
    """Seeds of a split (42 = 6 per category)."""
    if split not in ("held_out", "tune"):
        raise ValueError(f"split must be 'held_out' or 'tune', got {split!r}")
    return held_out_seeds(n) if split == "held_out" else tune_seeds(n)


def loop_length(span: plc.Span, load) -> float:
    """Loop length (m) at the load's frequency."""
    return float(span.loop_length(load_frequency(span, load)))


def load_frequency(span: plc.Span, load) -> float:
    if isinstance(load, plc.AeolianForce):
        return float(load.frequency_for(span.conductor))
    return float(load.frequency)


def _mode_near(freqs: np.ndarray, f: float) -> int:
    return int(np.argmin(np.abs(freqs - f))) + 1


def _node_positions_of_mode(model: plc.LineModel, mode: int) -> np.ndarray:
    """Interior zero crossings (m) of a bare mode's nodal shape."""
    shape = model.mode_shapes(mode)[:, mode - 1]
    x = model.node_positions
    crossings = []
    for j in range(1, x.size - 2):
        a, b = shape[j], shape[j + 1]
        if a == 0.0:
            crossings.append(x[j])
        elif a * b < 0:
            crossings.append(x[j] - a * (x[j + 1] - x[j]) / (b - a))
    return np.asarray(crossings)


def _start_position(rng, model, mode, span, loop, body):
    """Random start; 40 %: within 3 % of a loop of a vibration node of ``mode``."""
    lo, hi = max(0.05 * span.length, body / 2), min(0.95 * span.length, span.length - body / 2)
    if rng.random() < 0.4:
        nodes = _node_positions_of_mode(model, mode)
        nodes = nodes[(nodes > lo) & (nodes < hi)]
        if nodes.size:
            x = float(rng.choice(nodes)) + rng.uniform(-0.03, 0.03) * loop
            return float(np.clip(x, lo, hi)), "near a node"
    return float(rng.uniform(lo, hi)), "random"


def _sensors(rng, span, model, layout, n_sensors, first_load, load_scale, dt, damping, seed):
    x = model.node_positions
    allowed = np.flatnonzero((x > 0.02 * span.length) & (x < 0.98 * span.length))
    if layout == "random":
        return tuple(sorted(int(j) for j in rng.choice(allowed, n_sensors, replace=False)))
    # The toolbox's recipe on a short training record of the bare line: the first load plus a
    # broadband shaker (a single sine alone is not persistently exciting; see recipe.py).
    frequency = load_frequency(span, first_load)
    shaker = plc.RandomForce(0.1 * load_scale, float(rng.uniform(0.2, 0.4)) * span.length,
                             bandwidth=min(2.0 * frequency, 0.4 / dt), seed=seed + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        snap = plc.simulate(model, [first_load, shaker], duration=2.0, dt=dt,
                            noise_fraction=0.01, seed=seed)
        design = plc.design_estimator(snap, n_sensors, seed=seed, forbidden=[
            (0.0, 0.02 * span.length), (0.98 * span.length, span.length)])
    return tuple(sorted(int(j) for j in design.sensors))


def scenario(seed: int) -> Scenario:
    """The scenario of ``seed`` (deterministic; see the module doc)."""
    rng = np.random.default_rng(seed)
    category = CATEGORIES[(seed // 2) % len(CATEGORIES)]
    bc = str(rng.choice(["pinned", "clamped"]))
    layout = "toolbox" if rng.random() < 0.5 else "random"
    if category.startswith("lab/"):
        return _lab_scenario(seed, rng, category, bc, layout)
    return _real_scenario(seed, rng, category, bc, layout)


def _lab_scenario(seed, rng, category, bc, layout) -> Scenario:
    span = plc.Span.paper_lab()
    damping = plc.ModalDamping(float(rng.uniform(0.002, 0.005)))
    model = plc.LineModel(span, LAB_ELEMENTS, bc, damping=damping)
    freqs = model.natural_frequencies(8)
    duration = float(rng.integers(10, 15))
    amplitude = 1.0
    position = float(rng.uniform(0.1, 0.9)) * span.length

    def harmonic(kind, mode):
        if kind == "on":
            f = freqs[mode - 1] * rng.uniform(0.99, 1.01)
        else:
            f = freqs[mode - 1] + rng.uniform(0.3, 0.7) * (freqs[mode] - freqs[mode - 1])
        return plc.HarmonicForce(amplitude, float(f), position)

    if category == "lab/mode":
        first = harmonic("on", int(rng.integers(2, 6)))
        force = first
    elif category == "lab/between":
        first = harmonic("between", int(rng.integers(2, 5)))
        force = first
    elif category == "lab/wind-change":
        mode_a = int(rng.integers(2, 6))
        mode_b = int(rng.choice([m for m in range(2, 6) if m != mode_a]))
        first = harmonic("on", mode_a)
        second = harmonic(str(rng.choice(["on", "between"])), mode_b)
        duration = 14.0
        t1 = round(float(rng.uniform(0.3, 0.4)) * duration, 1)
        force = ((0.0, first), (t1, second))
    else:  # lab/aeolian: 0.8-2.2 m/s on 10.5 mm is 14-39 Hz (modes 2-5)
        first = plc.AeolianForce(wind_speed=round(float(rng.uniform(0.8, 2.2)), 3))
        force = first
        amplitude = first.lift_per_length(span.conductor) * span.length / 2
    f_first = load_frequency(span, first)
    mode = _mode_near(freqs, f_first)
    loop = loop_length(span, first)
    limits = plc.RobotLimits(0.5, 1.0)
    tuned = plc.tune_damper(model, mode, None, 0.04, body_mass=0.03)
    start, how = _start_position(rng, model, mode, span, loop, 0.0)
    robot = dataclasses.replace(tuned, position=start)
    n_sensors = int(rng.integers(3, 6))
    sensors = _sensors(rng, span, model, layout, n_sensors, first, amplitude, 1e-3, damping,
                       seed)
    description = (f"{category}, {bc}, zeta {damping.ratio:.4f}, {_describe(force, span)}, "
                   f"robot tuned to mode {mode}, start {start:.3f} m ({how}), "
                   f"{layout} sensors {list(sensors)}, {duration:g} s")
    return Scenario(seed, split_of(seed), category, span, bc, damping, force, robot, limits,
                    sensors, LAB_ELEMENTS, duration, 2.0, 1e-3, layout, description)


def _describe(force, span) -> str:
    def one(load):
        if isinstance(load, plc.AeolianForce):
            return f"aeolian {load.wind_speed:g} m/s ({load.frequency_for(span.conductor):.2f} Hz)"
        return f"harmonic {load.amplitude:g} N {load.frequency:.3f} Hz at {load.position:.3f} m"
    if isinstance(force, tuple):
        return " -> ".join(f"{one(load)} from {t:g} s" for t, load in force)
    return one(force)


def _real_scenario(seed, rng, category, bc, layout) -> Scenario:
    name = CONDUCTORS[(seed // 2) % len(CONDUCTORS)]
    length = round(float(rng.uniform(150.0, 450.0)), 1)
    fraction = round(float(rng.uniform(0.15, 0.25)), 3)
    span = plc.Span.at_rts_fraction(length, name, fraction)
    zeta = float(np.exp(rng.uniform(np.log(0.0005), np.log(0.005))))
    damping = plc.ModalDamping(zeta)
    cond = span.conductor
    # the wind whose lock-in is mode MAX_REAL_MODE at most
    f_cap = MAX_REAL_MODE * span.wave_speed / (2 * length)
    v_cap = f_cap * cond.diameter / DEFAULT_STROUHAL
    calibration, dt = 2.0, 0.002
    duration = float(rng.integers(24, 31))
    if category == "real/aeolian":
        first = plc.AeolianForce(wind_speed=round(min(float(rng.uniform(1.0, 4.0)), v_cap), 3))
        force = first
        f_top = load_frequency(span, first)
    elif category == "real/wind-change":
        v_a = min(float(rng.uniform(1.2, 3.5)), v_cap / 1.35)
        factor = float(rng.choice([-1, 1])) * float(rng.uniform(0.15, 0.35))
        v_b = v_a * (1 + factor)
        first = plc.AeolianForce(wind_speed=round(v_a, 3))
        second = plc.AeolianForce(wind_speed=round(v_b, 3))
        duration = 36.0
        t1 = round(float(rng.uniform(0.3, 0.4)) * duration, 1)
        force = ((0.0, first), (t1, second))
        f_top = max(load_frequency(span, first), load_frequency(span, second))
    else:
        f_top = None
    if name == "oxlip" or rng.random() < 0.5:
        f_mesh = 1.3 * (f_top if f_top is not None else f_cap)
        n_elements = int(math.ceil(8 * length / float(span.loop_length(f_mesh))))
    else:
        n_elements = None
    model = plc.LineModel(span, n_elements, bc, damping=damping)
    if category == "real/harmonic":
        n_top = int(min(MAX_REAL_MODE, 0.9 * f_cap * 2 * length / span.wave_speed))
        mode_n = int(rng.integers(20, max(21, n_top)))
        freqs = model.natural_frequencies(mode_n + 1)
        if rng.random() < 0.5:
            f = freqs[mode_n - 1] * rng.uniform(0.995, 1.005)
            kind = "on"
        else:
            f = freqs[mode_n - 1] + rng.uniform(0.3, 0.7) * (freqs[mode_n] - freqs[mode_n - 1])
            kind = "between"
        first = plc.HarmonicForce(5.0, float(f), float(rng.uniform(0.05, 0.95)) * length)
        force = first
        amplitude = 5.0
        category_detail = kind
    else:
        amplitude = first.lift_per_length(cond) * length / 2
        category_detail = ""
    f_first = load_frequency(span, first)
    freqs = model.natural_frequencies(min(model.n_dofs, int(2 * length * f_first
                                                          / span.wave_speed) + 6))
    mode = _mode_near(freqs, f_first)
    loop = loop_length(span, first)
    span_mass = cond.mass_per_length * length
    total = min(8.0, 0.03 * span_mass)
    body, absorber = 5.0 / 8.0 * total, 3.0 / 8.0 * total
    limits = plc.RobotLimits(1.0, 2.0, length=0.5)
    tuned = plc.tune_damper(model, mode, None, absorber, body_mass=body)
    start, how = _start_position(rng, model, mode, span, loop, limits.length)
    robot = dataclasses.replace(tuned, position=start)
    n_sensors = int(rng.integers(4, 8))
    sensors = _sensors(rng, span, model, layout, n_sensors, first, amplitude, dt, damping, seed)
    mesh = "physics mesh" if n_elements is None else f"{n_elements} el"
    description = (f"{category}{'/' + category_detail if category_detail else ''}, {name} "
                   f"{length:g} m at {fraction:.3f} RTS, {bc}, {mesh} ({model.n_elements} el), "
                   f"zeta {zeta:.5f}, {_describe(force, span)}, robot {body:.2f}+{absorber:.2f}"
                   f" kg tuned to mode {mode}, start {start:.2f} m ({how}), {layout} sensors "
                   f"{list(sensors)}, {duration:g} s")
    return Scenario(seed, split_of(seed), category, span, bc, damping, force, robot, limits,
                    sensors, n_elements, duration, calibration, dt, layout, description)


def off_nominal(seed: int) -> Scenario:
    """Scenario ``seed`` with the line off what the controller is told, as a real line is:
    tension +-10 % (a temperature swing), EI x0.7-1.3 (a stranded conductor's is known to a
    factor), line damping x0.3-3 and mass +-2 % (the catalogue's tolerance), drawn from their
    own stream (``70_000 + seed``). The span drawn by :func:`scenario` becomes the nominal; the
    load, robot and sensors are the engineer's choices from it. Sensors on a physics mesh are
    moved to the truth's node nearest to where they were (its mesh follows T and EI)."""
    told = scenario(seed)
    rng = np.random.default_rng(70_000 + seed)
    cond = told.span.conductor
    conductor = dataclasses.replace(
        cond, mass_per_length=cond.mass_per_length * float(rng.uniform(0.98, 1.02)),
        ei=cond.ei * float(rng.uniform(0.7, 1.3)))
    truth = plc.Span(told.span.length, told.span.tension * float(rng.uniform(0.9, 1.1)),
                     conductor)
    damping = plc.ModalDamping(float(told.damping.ratio)
                               * float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))))
    sensors = told.sensors
    if told.n_elements is None:
        x_told = plc.LineModel(told.span, None, told.bc).node_positions[list(sensors)]
        x_true = plc.LineModel(truth, None, told.bc).node_positions
        sensors = tuple(int(np.argmin(np.abs(x_true - x))) for x in x_told)
    deviation = (f"truth: tension {100 * (truth.tension / told.span.tension - 1):+.1f} %, EI "
                 f"x{conductor.ei / cond.ei:.2f}, damping x"
                 f"{damping.ratio / told.damping.ratio:.2f}, mass "
                 f"{100 * (conductor.mass_per_length / cond.mass_per_length - 1):+.1f} %")
    return dataclasses.replace(told, span=truth, damping=damping, sensors=sensors,
                               nominal=told.span,
                               description=f"{told.description}; {deviation}")


# ---------------------------------------------------------------------------------- the truth
class SteadyState:
    """Exact parked steady state of the full FE model under one harmonic load (see module doc).

    ``rms(p)``: span RMS with the robot parked at p (None: no robot on the line).
    """

    def __init__(self, span, n_elements, bc, damping, robot, load, modal_top: float = 3.0):
        self.span, self.n_elements, self.bc, self.robot = span, n_elements, bc, robot
        self.load = load
        self.damping = damping
        self.frequency = load_frequency(span, load)
        self.omega = 2 * np.pi * self.frequency
        self.bare = plc.LineModel(span, n_elements, bc)
        self.n_line = self.bare.n_dofs
        self.amplitude = load.amplitude if isinstance(load, plc.HarmonicForce) else 1.0
        x = self.bare.node_positions
        w = np.zeros_like(x)
        w[1:] += 0.5 * np.diff(x)
        w[:-1] += 0.5 * np.diff(x)
        self.weights = w / span.length
        self._lowrank = None
        self._c_line = None
        if isinstance(damping, plc.RayleighDamping):
            self._c_line = (damping.mass_coefficient * self.bare.mass_matrix
                            + damping.stiffness_coefficient * self.bare.stiffness_matrix)
        elif isinstance(damping, plc.ModalDamping):
            if self.n_line <= 400:
                basis = self.bare.modes(self.n_line)
            else:
                basis = self.bare.modes_below(modal_top * self.frequency)
            ratios = damping.ratios(basis.n_modes)
            if np.any(ratios > 0):
                u = self.bare.mass_matrix @ np.asarray(basis.shapes)   # (n_line, r)
                self._lowrank = (u, 2 * ratios * np.asarray(basis.omega))
        elif damping is not None:
            raise TypeError(f"unsupported damping {damping!r}")

    def _model(self, position):
        mdr = None if position is None else dataclasses.replace(self.robot, position=position)
        return plc.LineModel(self.span, self.n_elements, self.bc, mdr=mdr)

    def _load_vector(self, model):
        load = self.load
        if isinstance(load, plc.AeolianForce):
            return np.asarray(load.bind(model).load_vector(model), dtype=float)
        return self.amplitude * np.asarray(load.load_vector(model), dtype=float)

    def response(self, position) -> tuple[np.ndarray, object]:
        """Complex nodal amplitudes (n_nodes,) and the model, robot parked at ``position``."""
        model = self._model(position)
        w = self.omega
        n = model.n_dofs
        a = (model.stiffness_matrix - w**2 * model.mass_matrix).astype(complex) \
            + 1j * w * model.damper_matrix
        pad = n - self.n_line
        if self._c_line is not None:
            c = sp.block_diag([self._c_line, sp.csr_array((pad, pad))]) if pad else self._c_line
            a = a + 1j * w * c
        f = self._load_vector(model)
        lu = spla.splu(sp.csc_matrix(a))
        if self._lowrank is None:
            u = lu.solve(f.astype(complex))
        else:
            basis, d = self._lowrank
            big_u = np.vstack([basis, np.zeros((pad, basis.shape[1]))]) if pad else basis
            rhs = np.column_stack([f.astype(complex), big_u.astype(complex)])
            sol = lu.solve(rhs)
            x_f, x_u = sol[:, 0], sol[:, 1:]
            # (A + U D U^T)^-1 f = x_f - X_U (D^-1 + U^T X_U)^-1 U^T x_f,  D = i w diag(d)
            small = np.diag(1.0 / (1j * w * d)) + big_u.T @ x_u
            u = x_f - x_u @ np.linalg.solve(small, big_u.T @ x_f)
        return model.displacement_map() @ u, model

    def rms(self, position) -> float:
        """Span RMS (m) of the steady state, robot parked at ``position`` (None: no robot)."""
        nodal, _ = self.response(position)
        return float(np.sqrt(0.5 * self.weights @ np.abs(nodal) ** 2))


def reach_interval(scenario: Scenario) -> tuple[float, float]:
    """Where the best parked position is searched (see the module doc)."""
    span_length = scenario.span.length
    body = scenario.limits.length
    lo, hi = body / 2, span_length - body / 2
    if scenario.category.startswith("lab/"):
        return lo, hi
    budget = TRAVEL_FRACTION * (scenario.duration - scenario.calibration)
    a, b = 0.0, span_length
    for _ in range(60):  # rest_to_rest_time is increasing in the distance: bisection
        mid = 0.5 * (a + b)
        if scenario.limits.rest_to_rest_time(mid) <= budget:
            a = mid
        else:
            b = mid
    start = scenario.robot.position
    return max(lo, start - a), min(hi, start + a)


def best_parked(truth: SteadyState, lo: float, hi: float, step: float):
    """(best position, its RMS, grid positions, grid RMS): grid + refinement around the min."""
    n = max(3, int(math.ceil((hi - lo) / step)) + 1)
    grid = np.linspace(lo, hi, n)
    # a position exactly at a support is the same as no robot (pinned) or clamped: nudge inside
    grid = np.clip(grid, 1e-9, truth.span.length - 1e-9)
    values = np.array([truth.rms(p) for p in grid])
    i = int(np.argmin(values))
    h = grid[1] - grid[0]
    fine = np.clip(np.linspace(grid[i] - h, grid[i] + h, 21), lo + 1e-9, hi - 1e-9)
    fine_values = np.array([truth.rms(p) for p in fine])
    j = int(np.argmin(fine_values))
    positions = np.concatenate([grid, fine])
    rms = np.concatenate([values, fine_values])
    order = np.argsort(positions)
    if fine_values[j] <= values[i]:
        return float(fine[j]), float(fine_values[j]), positions[order], rms[order]
    return float(grid[i]), float(values[i]), positions[order], rms[order]


# ---------------------------------------------------------------------------------- the verdict
@dataclass(frozen=True)
class Outcome:
    """How one run went, judged by the independent truth (see the module doc)."""

    seed: int
    split: str
    category: str
    settled: bool
    range_fraction: float          # position range over the last quarter / loop length
    closed_over_best: float        # steady RMS at the final position / best within reach
    closed_over_start: float       # steady RMS at the final position / parked at the start
    final_position: float
    best_position: float
    start_position: float
    loop_length: float             # at the final load's frequency, m
    loops_from_best: float         # |final - best| / loop
    travel: float                  # total distance travelled, m
    rms_closed: float
    rms_best: float
    rms_start: float
    rms_no_robot: float
    reach: tuple
    truth: str                     # "steady" (exact) or "window" (non-harmonic load: flagged)
    cpu_time: float = float("nan")     # run_closed_loop's process time, s
    wall_time: float = float("nan")
    eval_time: float = float("nan")
    simulated: float = float("nan")    # simulated time, s
    retargets: int = 0
    loop_settled: bool = False         # run_closed_loop's own verdict
    warnings: tuple = ()
    error: str | None = None
    description: str = ""
    rms_clamp: float = float("nan")    # a fixed damper (the robot parked) near the left clamp

    @property
    def passed(self) -> bool:
        """Settled, <= 1.5x the best within reach and <= 1.05x the start."""
        return (self.error is None and self.settled and self.closed_over_best <= 1.5
                and self.closed_over_start <= 1.05)

    @property
    def real_time_factor(self) -> float:
        """Simulated time per CPU second of the run."""
        return self.simulated / self.cpu_time if self.cpu_time > 0 else float("nan")

    def row(self) -> dict:
        """JSON-ready dict."""
        out = dataclasses.asdict(self)
        out["reach"] = list(self.reach)
        out["warnings"] = list(self.warnings)
        out["passed"] = self.passed
        out["real_time_factor"] = self.real_time_factor
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in out.items()}


def _is_harmonic(load) -> bool:
    return isinstance(load, plc.HarmonicForce | plc.AeolianForce)


def evaluate(scenario: Scenario, result, **timing) -> Outcome:
    """Judge ``result`` (a ClosedLoopResult of ``scenario``) against the exact steady state."""
    t0 = time.process_time()
    span, load = scenario.span, scenario.final_load
    loop = loop_length(span, load)
    t = np.asarray(result.t)
    position = np.asarray(result.robot_position)
    last = t >= t[-1] - 0.25 * scenario.duration - 1e-12
    range_fraction = float(np.ptp(position[last]) / loop)
    final = float(position[-1])
    start = float(scenario.robot.position)
    lo, hi = reach_interval(scenario)
    if _is_harmonic(load):
        truth = SteadyState(span, scenario.n_elements, scenario.bc, scenario.damping,
                            scenario.robot, load)
        step = (truth.bare.element_length / 4 if scenario.category.startswith("lab/")
                else loop / 20)
        best, rms_best, _, _ = best_parked(truth, lo, hi, step)
        rms_closed, rms_start = truth.rms(final), truth.rms(start)
        rms_free = truth.rms(None)
        rms_clamp = truth.rms(min(0.05 * span.length, 1.5))
        kind = "steady"
    else:  # flagged: the run's own window RMS
        best, rms_best = float(result.best_position), result.comparison("best").rms
        rms_closed, rms_start = result.rms_closed_loop, result.rms_baseline
        rms_free = result.comparison("no_robot").rms
        rms_clamp = result.comparison("near_clamp").rms
        kind = "window"
    velocity = np.diff(position)
    return Outcome(
        seed=scenario.seed, split=scenario.split, category=scenario.category,
        settled=bool(range_fraction <= 0.02), range_fraction=range_fraction,
        closed_over_best=float(rms_closed / rms_best), closed_over_start=float(
            rms_closed / rms_start), final_position=final, best_position=float(best),
        start_position=start, loop_length=loop, loops_from_best=abs(final - best) / loop,
        travel=float(np.abs(velocity).sum()), rms_closed=float(rms_closed),
        rms_best=float(rms_best), rms_start=float(rms_start), rms_no_robot=float(rms_free),
        reach=(float(lo), float(hi)), truth=kind, eval_time=time.process_time() - t0,
        retargets=len(result.retarget_times), loop_settled=bool(result.settled),
        description=scenario.description, rms_clamp=float(rms_clamp), **timing)


def failure(scenario: Scenario, message: str, **timing) -> Outcome:
    """A row for a run that raised."""
    nan = float("nan")
    return Outcome(seed=scenario.seed, split=scenario.split, category=scenario.category,
                   settled=False, range_fraction=nan, closed_over_best=nan,
                   closed_over_start=nan, final_position=nan, best_position=nan,
                   start_position=float(scenario.robot.position),
                   loop_length=loop_length(scenario.span, scenario.final_load),
                   loops_from_best=nan, travel=nan, rms_closed=nan, rms_best=nan,
                   rms_start=nan, rms_no_robot=nan, reach=reach_interval(scenario),
                   truth="none", error=message, description=scenario.description, **timing)


def run(scenario: Scenario) -> Outcome:
    """Run the closed loop on ``scenario`` and judge it; an exception becomes a failure row.

    BLAS is limited to one thread for the call (threadpoolctl): on the shared 2-core machine
    multi-threaded BLAS made the same run 10-30x slower (measured 70 s instead of 7 s for a
    lab-span scenario under pytest, where no OPENBLAS_NUM_THREADS is set).
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return _run(scenario)


def _run(scenario: Scenario) -> Outcome:
    cpu, wall = time.process_time(), time.perf_counter()
    caught = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            args = scenario.run_arguments()
            result = plc.run_closed_loop(args.pop("span"), args.pop("force"),
                                         args.pop("robot"), args.pop("limits"), **args)
    except Exception as exc:  # noqa: BLE001 - every error becomes a failure row
        last = traceback.extract_tb(exc.__traceback__)[-1]
        return failure(scenario, f"{type(exc).__name__}: {exc} "
                       f"(at {last.filename.rsplit('/', 1)[-1]}:{last.lineno})",
                       cpu_time=time.process_time() - cpu,
                       wall_time=time.perf_counter() - wall)
    timing = dict(cpu_time=time.process_time() - cpu, wall_time=time.perf_counter() - wall,
                  simulated=float(scenario.duration),
                  warnings=tuple(sorted({w.category.__name__ for w in caught})))
    try:
        return evaluate(scenario, result, **timing)
    except Exception as exc:  # noqa: BLE001
        return failure(scenario, f"evaluator: {type(exc).__name__}: {exc}", **{
            k: v for k, v in timing.items() if k != "warnings"})


_THREAD_LIMIT = []


def pin_threads() -> None:
    """Limit BLAS to one thread in this process (a process-pool initializer)."""
    from threadpoolctl import threadpool_limits

    _THREAD_LIMIT.append(threadpool_limits(limits=1))


def run_seed(seed: int, truth_off_nominal: bool = False, calibrate: bool = True,
             told_truth: bool = False) -> Outcome:
    """Build scenario ``seed`` (:func:`off_nominal` with ``truth_off_nominal``, the controller
    calibrating its span from the records unless ``calibrate`` is False, or told that true line
    with ``told_truth``: the same line, what knowing it is worth) and run it (for process
    pools: only an int crosses over)."""
    from threadpoolctl import threadpool_limits

    try:
        with threadpool_limits(limits=1):
            sc = off_nominal(seed) if truth_off_nominal else scenario(seed)
            if not calibrate:
                sc = dataclasses.replace(sc, calibrate=False)
            if told_truth:
                sc = dataclasses.replace(sc, nominal=None)
    except Exception as exc:  # noqa: BLE001
        nan = float("nan")
        return Outcome(seed=seed, split=split_of(seed),
                       category=CATEGORIES[(seed // 2) % len(CATEGORIES)], settled=False,
                       range_fraction=nan, closed_over_best=nan, closed_over_start=nan,
                       final_position=nan, best_position=nan, start_position=nan,
                       loop_length=nan, loops_from_best=nan, travel=nan, rms_closed=nan,
                       rms_best=nan, rms_start=nan, rms_no_robot=nan, reach=(nan, nan),
                       truth="none", error=f"scenario generation: {type(exc).__name__}: {exc}")
    return run(sc)


# ---------------------------------------------------------------------------------- the table
@dataclass(frozen=True)
class Summary:
    """Family statistics of a list of outcomes."""

    label: str
    n: int
    errors: int
    median_best: float
    p90_best: float
    worst_best: float
    settled_fraction: float
    worst_start: float
    passed: int
    cpu_median: float
    rtf_median: float
    outcomes: tuple = field(default=(), repr=False)


def summarise(label: str, outcomes) -> Summary:
    outcomes = list(outcomes)
    ok = [o for o in outcomes if o.error is None]
    # an error counts as not settled and as an infinitely bad ratio
    best = np.array([o.closed_over_best if o.error is None else np.inf for o in outcomes])
    start = np.array([o.closed_over_start if o.error is None else np.inf for o in outcomes])
    cpu = np.array([o.cpu_time for o in ok]) if ok else np.array([np.nan])
    rtf = np.array([o.real_time_factor for o in ok]) if ok else np.array([np.nan])
    n = len(outcomes)
    return Summary(
        label, n, n - len(ok),
        float(np.median(best)) if n else np.nan,
        float(np.percentile(best, 90)) if n else np.nan,
        float(np.max(best)) if n else np.nan,
        float(np.mean([o.settled for o in outcomes])) if n else np.nan,
        float(np.max(start)) if n else np.nan,
        sum(o.passed for o in outcomes),
        float(np.median(cpu)), float(np.median(rtf)), tuple(outcomes))


def criteria_failures(summary: Summary) -> list[str]:
    """The family criteria a summary misses (empty: all met): settled in 95 % of runs, median
    closed/best <= 1.10, worst closed/best <= 1.5, worst closed/start <= 1.05, no errors."""
    problems = []
    if summary.settled_fraction < 0.95:
        problems.append(f"settled in {100 * summary.settled_fraction:.0f} % of runs (< 95 %)")
    if not summary.median_best <= 1.10:
        problems.append(f"median closed/best {summary.median_best:.3f} (> 1.10)")
    if not summary.worst_best <= 1.5:
        problems.append(f"worst closed/best {summary.worst_best:.3f} (> 1.5)")
    if not summary.worst_start <= 1.05:
        problems.append(f"worst closed/start {summary.worst_start:.3f} (> 1.05)")
    if summary.errors:
        problems.append(f"{summary.errors} run(s) raised")
    return problems


def format_table(outcomes) -> str:
    """The family table: per category and overall."""
    outcomes = list(outcomes)
    rows = [summarise(c, [o for o in outcomes if o.category == c]) for c in CATEGORIES]
    rows = [r for r in rows if r.n]
    rows.append(summarise("lab (all)", [o for o in outcomes if o.category.startswith("lab/")]))
    rows.append(summarise("real (all)", [o for o in outcomes if o.category.startswith("real/")]))
    rows.append(summarise("overall", outcomes))
    head = (f"{'category':18s} {'n':>3s} {'err':>3s} {'med c/b':>8s} {'p90 c/b':>8s} "
            f"{'worst c/b':>9s} {'settled':>7s} {'worst c/s':>9s} {'pass':>5s} "
            f"{'cpu s':>6s} {'RTFcpu':>6s}")
    lines = [head, "-" * len(head)]
    for r in rows:
        if not r.n:
            continue
        lines.append(f"{r.label:18s} {r.n:3d} {r.errors:3d} {r.median_best:8.3f} "
                     f"{r.p90_best:8.3f} {r.worst_best:9.3f} {100 * r.settled_fraction:6.0f}% "
                     f"{r.worst_start:9.3f} {r.passed:2d}/{r.n:<2d} {r.cpu_median:6.1f} "
                     f"{r.rtf_median:6.2f}")
    return "\n".join(lines)
