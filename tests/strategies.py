"""Hypothesis strategies for the reliability suite, kept in one place.

Every strategy draws *valid* inputs only (the bad-input table in ``test_reliability.py`` covers
invalid ones), in ranges that keep one example cheap (small meshes, short records).
"""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import strategies as st

import powerline_control as plc
from powerline_control import scenario as config  # the schema, its sections and files


def reals(low: float, high: float) -> st.SearchStrategy[float]:
    """Finite floats in [low, high], drawn on a log scale when the range spans decades."""
    if low > 0 and high / low > 100:
        return st.floats(np.log10(low), np.log10(high)).map(lambda e: float(10.0**e))
    return st.floats(low, high, allow_nan=False, allow_infinity=False)


seeds = st.integers(0, 2**32 - 1)

conductors = st.builds(
    plc.Conductor,
    mass_per_length=reals(0.05, 5.0),   # kg/m: from thin earth wires to large ACSR
    diameter=reals(0.004, 0.06),        # m
    ei=reals(0.5, 5000.0),              # N m^2
)


@st.composite
def spans(draw) -> plc.Span:
    return plc.Span(length=draw(reals(1.0, 500.0)), tension=draw(reals(10.0, 1e5)),
                    conductor=draw(conductors))


boundary_conditions = st.sampled_from(
    ["pinned", "clamped", ("pinned", "clamped"), ("clamped", "pinned")]
)
dampings = st.one_of(
    st.none(),
    st.builds(plc.ModalDamping, reals(1e-4, 0.2)),
    st.builds(plc.RayleighDamping, reals(0.0, 1.0), reals(0.0, 1e-3)),
)


@st.composite
def line_models(draw, max_elements: int = 12) -> plc.LineModel:
    """Small FE models with any supports, damping and (optionally) a robot anywhere on the span."""
    span = draw(spans())
    mdr = None
    if draw(st.booleans()):
        position = draw(st.floats(0.0, 1.0)) * span.length
        suspended = draw(st.sampled_from([0.0, 0.05, 1.0]))
        mdr = plc.MDR(position=position, body_mass=draw(reals(0.0, 2.0)),
                      suspended_mass=suspended,
                      stiffness=draw(reals(1.0, 1e5)) if suspended > 0 else 0.0,
                      damping=draw(reals(0.0, 10.0)) if suspended > 0 else 0.0)
    bc = draw(boundary_conditions)
    # One element between two clamps has no free DOF: LineModel rejects it (a bad-input row).
    fewest = 2 if bc in ("clamped", ("clamped", "clamped")) else 1
    with warnings.catch_warnings():
        # A coarse uniform mesh at a clamp is valid but does not resolve the boundary layer:
        # it warns (the clamp's boundary layer unresolved); these strategies test properties that
        # hold on any mesh.
        warnings.filterwarnings("ignore", "The uniform mesh .* boundary layer",
                                plc.TruncationWarning)
        return plc.LineModel(span, n_elements=draw(st.integers(fewest, max_elements)),
                             bc=bc, damping=draw(dampings), mdr=mdr)


@st.composite
def dmd_models(draw) -> plc.DMDModel:
    """DMD models of every saved variant: delays, rank, inputs (B), alpha modes."""
    rng = np.random.default_rng(draw(seeds))
    n_nodes = draw(st.integers(1, 5))
    delays = draw(st.integers(1, 3))
    # Enough snapshot pairs for plain DMD of every state and input (fit_dmd rejects fewer).
    n_samples = draw(st.integers(2 * n_nodes * delays + 10, 2 * n_nodes * delays + 40))
    X = rng.standard_normal((n_nodes, n_samples))
    rank = draw(st.one_of(st.none(), st.integers(1, n_nodes * delays)))
    inputs = rng.standard_normal((draw(st.integers(1, 2)), n_samples)) if draw(st.booleans()) \
        else None
    alpha_mode = draw(st.sampled_from(["absolute", "relative"]))
    alpha = draw(st.sampled_from([0.0, 1e-6, 0.1, 1.0])) if alpha_mode == "absolute" \
        else draw(st.sampled_from([1e-6, 1e-3, 0.5]))
    dt = draw(reals(1e-4, 1.0))
    if draw(st.booleans()) and rank is None:
        # The other producer of DMDModel: the recursive-least-squares OnlineDMD.
        n_start = n_samples // 2
        online = plc.OnlineDMD(X[:, :n_start], dt, delays=delays,
                               inputs=None if inputs is None else inputs[:, :n_start],
                               forgetting=draw(st.sampled_from([1.0, 0.99])),
                               alpha=1e-3 if alpha_mode == "absolute" else 0.0)
        for k in range(n_start, n_samples):
            online.update(X[:, k], None if inputs is None else inputs[:, k])
        return online.model()
    return plc.fit_dmd(X, dt=dt, alpha=alpha, delays=delays, rank=rank, inputs=inputs,
                       alpha_mode=alpha_mode)


# ------------------------------------------------------------------------- scenarios
_toml_floats = reals(1e-3, 1e3)  # any finite float round-trips through repr()


@st.composite
def scenarios(draw, numeric_alpha: bool = False) -> config.Scenario:
    """Valid scenarios: every value inside what the schema allows, positions on the span.

    Keys that do not apply (a conductor with the lab preset, a frequency with the aeolian load)
    keep their defaults: a template writes them commented out, as a file would leave them.
    ``numeric_alpha`` also draws a number for ``identification.alpha`` (the documented
    ``float | str`` field).
    """
    preset = draw(st.sampled_from(["paper_lab", "conductor"]))
    span = config.SpanConfig(preset=preset)
    if preset == "conductor":
        span = config.SpanConfig(preset=preset, conductor=draw(st.sampled_from(sorted(
            plc.conductors))), length=draw(reals(10.0, 1000.0)),
            rts_fraction=draw(reals(0.05, 0.4)))
    length = span.length if preset == "conductor" else plc.Span.paper_lab().length
    n_elements = draw(st.integers(2, 5000))
    model = config.ModelConfig(n_elements=n_elements,
                               bc=draw(st.sampled_from(["pinned", "clamped"])),
                               damping_ratio=draw(st.floats(0.0, 0.9)))
    dt = draw(reals(1e-5, 1e-1))
    simulation = config.SimulationConfig(duration=min(3600.0, dt * draw(st.integers(60, 10**6))),
                                         dt=dt,
                                         noise_fraction=draw(st.floats(0.0, 0.99)),
                                         seed=draw(st.integers(0, 2**31)))
    kind = draw(st.sampled_from(["harmonic", "aeolian", "random"]))
    on_span = st.floats(0.01, 0.99).map(lambda f: f * length)
    if kind == "harmonic":
        forcing = config.ForcingConfig(kind=kind, amplitude=draw(_toml_floats),
                                       frequency=draw(reals(1e-3, min(1e4, 0.49 / dt))),
                                       position=draw(on_span))
    elif kind == "aeolian":
        forcing = config.ForcingConfig(kind=kind, wind_speed=draw(reals(0.1, 30.0)))
    else:
        forcing = config.ForcingConfig(kind=kind, amplitude=draw(_toml_floats),
                                       position=draw(on_span), bandwidth=draw(_toml_floats),
                                       seed=draw(st.integers(0, 2**31)))
    alpha = draw(st.one_of(st.just("auto"), reals(1e-8, 1.0))) if numeric_alpha else "auto"
    identification = config.IdentificationConfig(
        delays=draw(st.integers(1, 4)), alpha=alpha,
        rank=draw(st.one_of(st.none(), st.integers(1, 500))))
    sensors = draw(st.one_of(st.none(), st.lists(st.integers(1, n_elements - 1), min_size=1,
                                                 max_size=6, unique=True).map(tuple)))
    estimation = (config.EstimationConfig(sensors=sensors) if sensors is not None
                  else config.EstimationConfig(n_sensors=draw(st.integers(1, 20))))
    robot = config.RobotConfig(
        start=draw(on_span), body_mass=draw(reals(1e-3, 1e3)),
        suspended_mass=draw(reals(1e-3, 1e3)), damping_ratio=draw(st.floats(0.01, 0.99)),
        v_max=draw(reals(1e-3, 20.0)), a_max=draw(reals(1e-3, 100.0)),
        closed_loop=_closed_loop(draw(st.floats(0.0, min(600.0, 10 * simulation.duration))),
                                 dt))
    return config.Scenario(span=span, model=model, truth=draw(truths(preset)), forcing=forcing,
                           simulation=simulation, identification=identification,
                           estimation=estimation, robot=robot)


def _closed_loop(seconds: float, dt: float) -> float:
    """``seconds``, or 0 (no closed loop) when its calibration (a third of it, at most 2 s, in
    whole 50 ms control periods) would hold too few samples for the estimator's recipe: the
    schema refuses such a closed loop (a 1.2x margin and one period keep clear of rounding)."""
    from powerline_control.recipe.defaults import shortest_record

    return seconds if min(2.0, seconds / 3) >= 1.2 * shortest_record() * dt + 0.05 else 0.0


@st.composite
def truths(draw, preset: str) -> config.TruthConfig:
    """A scenario's [truth]: a temperature (conductor presets only: the lab conductor has no
    change of state) or a tension factor or neither, and the conductor's factors and damping."""
    tension = draw(st.sampled_from(["none", "factor"] + (["temperature"]
                                                          if preset == "conductor" else [])))
    keys = {"ei_factor": draw(reals(0.2, 5.0)), "mass_factor": draw(reals(0.8, 1.2)),
            "damping_ratio": draw(st.one_of(st.none(), st.floats(0.0, 0.9)))}
    if tension == "factor":
        keys["tension_factor"] = draw(reals(0.5, 1.5))
    elif tension == "temperature":   # within 30 degC of the stringing: far from the rated strength
        stringing = draw(reals(-10.0, 30.0))
        keys.update(stringing_temperature=stringing,
                    temperature=draw(reals(stringing - 30.0, stringing + 30.0)))
    return config.TruthConfig(**keys)


# ------------------------------------------------------------------------- sensor constraints
@st.composite
def sensor_constraints(draw, positions: np.ndarray, k: int) -> dict:
    """A random mix of forbidden zones, spacing, required nodes and a cost budget.

    Drawn without regard to feasibility: infeasible sets must be reported, not mis-solved.
    """
    length = float(positions[-1])
    m = positions.size
    options: dict = {}
    if draw(st.booleans()):
        zones = []
        for _ in range(draw(st.integers(1, 2))):
            a, b = sorted(draw(st.floats(0.0, 1.0)) * length for _ in range(2))
            zones.append((a, b))
        options["forbidden"] = zones
    if draw(st.booleans()):
        options["min_spacing"] = draw(st.floats(0.0, 0.4)) * length
    if draw(st.booleans()):
        options["required"] = sorted(set(draw(st.lists(st.integers(0, m - 1), min_size=1,
                                                       max_size=max(1, k - 1)))))
    if draw(st.booleans()):
        cost = np.array(draw(st.lists(st.integers(1, 3), min_size=m, max_size=m)), float)
        options["cost"] = cost
        options["budget"] = float(draw(st.integers(k, 3 * k)))
    return options
