"""A seeded family of records whose line is not the nominal one, for :func:`calibrate_span`.

Used by ``tests/test_calibration.py`` and ``benchmarks/bench_calibrate.py``; not a test file.

``case(seed)`` is a pure function of the seed. The split is the seed's parity: even seeds tuned
the calibration's settings, odd seeds are held out. The span cycles over the lab span and every
preset (150-450 m at 15-25 % RTS), supports pinned or clamped, the load over a harmonic point
load near a mode, aeolian lock-in and a broadband point shaker; 3-6 sensors at random interior
positions (not within 2 % of the span from a support); a record of 10-60 s (10-20 s on the lab
span) with 1 % sensor noise. The truth deviates from the nominal as a real line does: tension
+-10 %, EI x0.7-1.3 (x0.5-2 for the lab's solid rod: it is nominal), line damping 0.05-0.5 %
(log-uniform), mass +-2 % (the catalogue's tolerance).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

import powerline_control as plc

LOADS = ("harmonic", "aeolian", "broadband")
SPANS = ("lab",) + tuple(plc.conductors)


@dataclass(frozen=True)
class CalibrationCase:
    """One record, the nominal span it is read against, and the truth."""

    seed: int
    label: str
    record: plc.Record
    nominal: plc.Span
    bc: str
    truth: plc.Span
    damping: float


def _truth(nominal: plc.Span, rng: np.random.Generator, lab: bool) -> plc.Span:
    ei_factor = rng.uniform(0.5, 2.0) if lab else rng.uniform(0.7, 1.3)
    conductor = dataclasses.replace(
        nominal.conductor,
        mass_per_length=nominal.conductor.mass_per_length * rng.uniform(0.98, 1.02),
        ei=nominal.conductor.ei * ei_factor,
    )
    return plc.Span(nominal.length, nominal.tension * rng.uniform(0.9, 1.1), conductor)


def case(seed: int) -> CalibrationCase:
    """The record of seed ``seed`` (module doc)."""
    rng = np.random.default_rng(10_000 + seed)
    kind = SPANS[seed // 2 % len(SPANS)]
    load_kind = LOADS[seed // 2 % len(LOADS)] if seed % 4 < 2 else LOADS[(seed // 2 + 1) % 3]
    bc = str(rng.choice(["pinned", "clamped"]))
    lab = kind == "lab"
    if lab:
        nominal = plc.Span.paper_lab()
        duration, dt = float(rng.uniform(10.0, 20.0)), 1e-3
    else:
        length = float(rng.uniform(150.0, 450.0))
        nominal = plc.Span.at_rts_fraction(length, kind, float(rng.uniform(0.15, 0.25)))
        duration, dt = float(rng.uniform(10.0, 60.0)), 2e-3
    truth = _truth(nominal, rng, lab)
    zeta = float(np.exp(rng.uniform(np.log(5e-4), np.log(5e-3))))
    d = truth.conductor.diameter
    if lab:
        mesh = {"n_elements": 40}
        top = 120.0
    else:
        # aeolian band 1.5-5 m/s; the physics mesh, graded toward clamps, resolves its top
        top = float(min(0.185 * 5.0 / d, 0.3 / dt))
        mesh = {"n_elements": None, "max_frequency": 1.2 * top}
    model = plc.LineModel(truth, bc=bc, damping=plc.ModalDamping(zeta), **mesh)
    x_load = float(rng.uniform(0.05, 0.45)) * truth.length
    if load_kind == "aeolian":
        wind = float(rng.uniform(1.5, 5.0)) if not lab else float(rng.uniform(1.0, 3.0))
        force = plc.AeolianForce(wind_speed=wind)
        if lab:
            force = plc.AeolianForce(wind_speed=wind, lift_coefficient=0.05)
    elif load_kind == "harmonic":
        f_hi = 100.0 if lab else top * 0.8
        f_modes = model.modes_below(f_hi).frequencies
        candidates = f_modes[(f_modes > (5.0 if lab else 8.0)) & (f_modes < f_hi)]
        f_n = float(rng.choice(candidates))
        force = plc.HarmonicForce(1.0, f_n * rng.uniform(0.99, 1.01), x_load)
    else:
        force = plc.RandomForce(0.5 if lab else 20.0, x_load,
                                bandwidth=100.0 if lab else top, seed=int(seed))
    snap = plc.simulate(model, force, duration=duration, dt=dt, noise_fraction=0.01,
                        seed=int(seed))
    n_sensors = int(rng.integers(3, 7))
    margin = 0.02 * truth.length
    positions = np.sort(rng.uniform(margin, truth.length - margin, n_sensors))
    nodes = np.unique([int(np.argmin(np.abs(snap.x - p))) for p in positions])
    record = plc.Record(snap.t, snap.x[nodes], snap.displacement[nodes],
                        source=f"calibration family seed {seed}")
    label = f"{kind} {bc} {load_kind} {truth.length:.0f} m {duration:.0f} s {nodes.size} sensors"
    return CalibrationCase(seed=seed, label=label, record=record, nominal=nominal, bc=bc,
                           truth=truth, damping=zeta)


def held_out_seeds(n: int) -> list[int]:
    """The first ``n`` held-out seeds (odd)."""
    return [2 * i + 1 for i in range(n)]


def tune_seeds(n: int) -> list[int]:
    """The first ``n`` tuning seeds (even)."""
    return [2 * i for i in range(n)]
