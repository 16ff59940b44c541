"""The bad-input sweep of every public name: valid baseline calls, the bad values, a guarded worker.

Every public callable of ``powerline_control.__all__`` (and the public methods users call on the
objects it returns) has one *baseline*: a minimal valid call, written below as a function of a
kit of small valid objects. The sweep binds the baseline to the callable's signature
(``inspect.signature``), then replaces one parameter at a time by a bad value chosen from the
baseline value's kind (a number, an integer, a flag, a string, an array, an object, a path):
NaN, +-inf, negative, zero, huge, tiny, the wrong type, the wrong shape, transposed, empty, text
for a number, a bool for a number, a folder / FIFO / binary file for a path.

A case is identified by ``name::parameter::kind`` and run in a worker subprocess (this file run
as a script) under an address-space limit (``resource.setrlimit(RLIMIT_AS)``) with the package's
memory budget lowered below it, so that an allocation the budget should have refused ends as a
``MemoryError`` in the worker, not as a swapping test machine; the parent kills a worker that
does not answer in time (a hang). Outcomes:

``own``      the package's own error (``PowerlineControlError`` that is a ``ValueError`` or a
             ``TypeError``) whose message names the parameter: the right answer to bad input;
``unnamed``  the package's own error, but the message does not name the parameter;
``runtime``  the package's own ``RuntimeError`` family (model, planning, ...) for bad input;
``raw``      any other exception (a NumPy/SciPy error, a ``TypeError`` from Python, ...);
``memory``   ``MemoryError`` under the address-space limit (an allocation before a size check);
``accepted`` a normal return: right only where :data:`ACCEPTED` says why the value is valid;
``hang``     no answer within the timeout (set by the parent);
``crash``    the worker died (a signal).
"""

from __future__ import annotations

import inspect
import json
import math
import os
import sys
import tempfile
import time
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path

WORKER_MEMORY_LIMIT = 2 * 2**30        # address space of a worker (imports take ~0.4 GiB)
WORKER_BUDGET = 256 * 2**20            # the package's memory budget inside a worker


# ============================================================================ the valid kit
class Kit:
    """Small valid objects, built once per process on first use (cheap: well under a second)."""

    def __init__(self) -> None:
        import numpy as np

        import powerline_control as plc

        self.np, self.plc = np, plc
        rng = np.random.default_rng(0)
        self.lab = plc.Span.paper_lab()
        self.cond = self.lab.conductor
        self.model = plc.LineModel(self.lab, n_elements=10)
        self.X = rng.standard_normal((4, 60))
        self.X_long = rng.standard_normal((4, 400))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.dmd = plc.fit_dmd(self.X, dt=1e-3, alpha=1e-3)
        self.sys = self.dmd.to_statespace(measured=[0, 1])
        self.sys_all = self.dmd.to_statespace()
        self.q = self.dmd.residual_covariance
        self.kf = plc.KalmanFilter(self.sys, Q=self.q, R=1e-4)
        self.est = self.kf.filter(self.X[:2, :20])
        self.field = (np.sin(np.pi * np.linspace(0, 1, 11))[:, None]
                      * np.cos(np.linspace(0, 20, 50)))
        self.antinodes = plc.locate_antinodes(self.field, self.model.node_positions)
        self.limits = plc.RobotLimits(v_max=0.5, a_max=1.0)
        self.mdr = plc.MDR(1.2, 0.02)
        self.force = plc.HarmonicForce(1.0, 9.0, 1.1)
        self.snap = plc.simulate(self.model, self.force, duration=0.2, dt=1e-3, seed=0)
        self.tmp = Path(tempfile.mkdtemp(prefix="plc-sweep-"))
        self.model_file = self.tmp / "model.npz"
        plc.save_model(self.model_file, self.dmd)
        self.study = plc.run_study(_study_point, plc.parameter_grid(a=[1.0, 2.0]),
                                   progress=False)
        self.study_file = self.study.to_json(self.tmp / "study.json")
        self.wind = plc.severity.WindDistribution.weibull()
        self.planner = plc.MotionPlanner(self.limits, span_length=3.66)
        self.online = plc.OnlineDMD(self.X[:, :20], dt=1e-3)

    def wind_csv(self) -> str:
        csv = self.tmp / "wind.csv"
        if not csv.exists():
            csv.write_text("time,wind_speed,direction,temperature\n0,3.0,90,12\n600,4.0,80,11.5\n")
        return str(csv)

    def count_record(self):
        """A 1 s broadband record of the lab span (20 elements) for estimator_count_study."""
        if not hasattr(self, "_count_record"):
            model = self.plc.LineModel(self.lab, n_elements=20)
            self._count_record = self.plc.simulate(
                model, self.plc.RandomForce(1.0, 1.3, 80.0, seed=2), 1.0, 1e-3,
                noise_fraction=0.01, seed=0)
        return self._count_record

    def ringing_record(self):
        """Three channels of the lab span's first four pinned modes ringing for 2 s (closed-form
        frequencies of the 10-element model), a record calibrate_span reads."""
        np, plc = self.np, self.plc
        t = 1e-3 * np.arange(2001)
        x = np.array([0.7, 1.6, 2.9])
        f = self.model.natural_frequencies(4)
        shapes = np.sin(np.outer(x, np.arange(1, 5)) * np.pi / self.lab.length)
        values = shapes @ (1e-3 * np.cos(2 * np.pi * np.outer(f, t) + np.arange(4)[:, None]))
        return plc.Record(t, x, values)

    def record_csv(self) -> str:
        csv = self.tmp / "field.csv"
        if not csv.exists():
            csv.write_text("time_s,x_0.9_mm,x_2.4_mm\n0,0.1,0.2\n0.001,,0.3\n0.002,0.2,0.1\n")
        return str(csv)

    def truth_scenario(self):
        """The lab scenario with a [truth] section (the true tension 3 % below the nominal)."""
        return self.plc.load_scenario(text="[truth]\ntension_factor = 0.97")

    def clamp_design(self):
        """(design, its sensors' record, node positions) on a clamped Drake span (slow: ~2 s)."""
        if not hasattr(self, "_clamp"):
            plc, np = self.plc, self.np
            span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
            model = plc.LineModel(span, bc="clamped", max_frequency=8.0)
            load = [plc.HarmonicForce(5.0, 3.0, 61.0), plc.RandomForce(1.0, 130.0, 6.0, seed=1)]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                train = plc.simulate(model, load, 6.0, 4e-3, noise_fraction=0.01, seed=0)
                design = plc.design_estimator(train, n_sensors=5, seed=0)
            self._clamp = (design, np.asarray(train.displacement[design.sensors]),
                           model.node_positions)
        return self._clamp

    # bad paths, made on first use (a FIFO opened for reading would block: the timeout catches it)
    def path(self, kind: str) -> str:
        if kind == "folder":
            folder = self.tmp / "a-folder"
            folder.mkdir(exist_ok=True)
            return str(folder)
        if kind == "fifo":
            fifo = self.tmp / "a-fifo"
            if not fifo.exists():
                os.mkfifo(fifo)
            return str(fifo)
        if kind == "binary":
            binary = self.tmp / "binary.bin"
            binary.write_bytes(bytes(range(256)) * 16)
            return str(binary)
        if kind == "missing_dir":
            return str(self.tmp / "no" / "such" / "dir" / "file")
        raise KeyError(kind)


def _study_point(a, seed=None):
    return {"b": 2.0 * a}


_KIT: Kit | None = None


def kit() -> Kit:
    global _KIT
    if _KIT is None:
        _KIT = Kit()
    return _KIT


# ============================================================================ baselines
@dataclass(frozen=True)
class Baseline:
    """A minimal valid call: ``make(kit) -> (callable, {parameter: value})``."""

    make: object
    slow: bool = False              # the whole name's cases run only with the slow marker
    skip: tuple = ()                # parameters not swept (with the reason in a comment)


def _b(make, **options) -> Baseline:
    return Baseline(make, **options)


# run_closed_loop's parameters but nominal (swept once, by the "run_closed_loop" row).
_RUN_CLOSED_LOOP_PARAMETERS = (
    "model", "force", "robot", "limits", "sensors", "n_elements", "bc", "damping", "duration",
    "calibration", "dt", "control_period", "plant_period", "noise_fraction", "delays",
    "estimator_rank", "antinode_window", "frequency_window", "retarget_threshold",
    "settle_margin", "n_modes", "clamp_distance", "obstacles", "motion", "planner_time_budget",
    "seed", "calibrate", "settings", "aeolian_steady", "wind")


BASELINES: dict[str, Baseline] = {
    # ---------------------------------------------------------------- line
    "Conductor": _b(lambda k: (k.plc.Conductor, dict(mass_per_length=1.6, diameter=0.028, ei=44.0,
                                                     rated_strength=140e3, name="c"))),
    "Conductor.tension_at": _b(lambda k: (k.plc.conductors["drake"].tension_at,
                                          dict(fraction_of_rts=0.2))),
    "Span": _b(lambda k: (k.plc.Span, dict(length=300.0, tension=28e3,
                                           conductor=k.plc.conductors["drake"]))),
    "Span.at_rts_fraction": _b(lambda k: (k.plc.Span.at_rts_fraction,
                                          dict(length=300.0, conductor="drake",
                                               fraction_of_rts=0.2))),
    "Span.paper_lab": _b(lambda k: (k.plc.Span.paper_lab, dict(mass_reading="total"))),
    "Span.pinned_frequencies": _b(lambda k: (k.lab.pinned_frequencies, dict(n_modes=3))),
    "Span.loop_length": _b(lambda k: (k.lab.loop_length, dict(frequency=10.0))),
    # ---------------------------------------------------------------- loads
    "HarmonicForce": _b(lambda k: (k.plc.HarmonicForce, dict(amplitude=1.0, frequency=9.0,
                                                             position=1.1, phase=0.0))),
    "AeolianForce": _b(lambda k: (k.plc.AeolianForce, dict(wind_speed=3.0))),
    "RandomForce": _b(lambda k: (k.plc.RandomForce, dict(std=1.0, position=1.0))),
    "strouhal_frequency": _b(lambda k: (k.plc.excitation.strouhal_frequency,
                                        dict(wind_speed=3.0, diameter=0.02))),
    # ---------------------------------------------------------------- physics
    "LineModel": _b(lambda k: (k.plc.LineModel, dict(span=k.lab, n_elements=10))),
    "LineModel.physics": _b(lambda k: (k.plc.LineModel,
                                       dict(span=k.lab, bc="clamped", max_frequency=60.0)),
                            skip=("n_elements", "damping", "mdr")),
    "LineModel.natural_frequencies": _b(lambda k: (k.model.natural_frequencies,
                                                   dict(n_modes=3))),
    "LineModel.to_statespace": _b(lambda k: (k.model.to_statespace,
                                             dict(dt=1e-3, force_positions=(1.0,),
                                                  outputs=[0.5, 1.5], n_modes=4))),
    "LineModel.shape_vector": _b(lambda k: (k.model.shape_vector, dict(position=1.0))),
    "MDR": _b(lambda k: (k.plc.MDR, dict(position=1.2, body_mass=0.02, suspended_mass=0.01,
                                         stiffness=100.0, damping=0.1))),
    "ModalDamping": _b(lambda k: (k.plc.ModalDamping, dict(ratio=0.01))),
    "RayleighDamping": _b(lambda k: (k.plc.RayleighDamping,
                                     dict(mass_coefficient=0.1, stiffness_coefficient=1e-4))),
    "tune_damper": _b(lambda k: (k.plc.tune_damper, dict(model=k.model, mode=1, position=1.0,
                                                         mass=0.05))),
    "den_hartog_optimum": _b(lambda k: (k.plc.fem.den_hartog_optimum, dict(mass_ratio=0.05))),
    # ---------------------------------------------------------------- data
    "simulate": _b(lambda k: (k.plc.simulate, dict(model=k.model, force=k.force, duration=0.05,
                                                   dt=1e-3, seed=0))),
    "fit_dmd": _b(lambda k: (k.plc.fit_dmd, dict(X=k.X, dt=1e-3, alpha=1e-3))),
    "select_alpha": _b(lambda k: (k.plc.select_alpha, dict(X=k.X_long, dt=1e-3,
                                                           alphas=[1e-4, 1e-2], horizon=20,
                                                           n_windows=2))),
    "OnlineDMD": _b(lambda k: (k.plc.OnlineDMD, dict(X=k.X[:, :20], dt=1e-3))),
    "OnlineDMD.update": _b(lambda k: (k.plc.OnlineDMD(k.X[:, :20], dt=1e-3).update,
                                      dict(x=k.X[:, 20]))),
    "DMDModel.predict": _b(lambda k: (k.dmd.predict, dict(initial=k.dmd.initial_state,
                                                          n_steps=5))),
    "DMDModel.to_statespace": _b(lambda k: (k.dmd.to_statespace, dict(measured=[0, 1]))),
    "OscillatorModel.from_lines": _b(lambda k: (k.plc.identify.OscillatorModel.from_lines, dict(
        frequencies=[3.0, 7.0], shapes=[[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]], dt=0.01, n_pairs=100,
        process_noise=1e-6, unseen=None, unseen_noise=0.0, radius=1 - 1e-6))),
    "save_model": _b(lambda k: (k.plc.save_model, dict(path=str(k.tmp / "out.npz"),
                                                       model=k.dmd))),
    "load_model": _b(lambda k: (k.plc.load_model, dict(path=str(k.model_file)))),
    # ---------------------------------------------------------------- estimation
    "KalmanFilter": _b(lambda k: (k.plc.KalmanFilter, dict(sys=k.sys, Q=k.q, R=1e-4))),
    "KalmanFilter.filter": _b(lambda k: (k.kf.filter, dict(measurements=k.X[:2, :20]))),
    "KalmanFilter.step": _b(lambda k: (k.plc.KalmanFilter(k.sys, Q=k.q, R=1e-4).step,
                                       dict(y_k=k.X[:2, 0]))),
    "recovery_time": _b(lambda k: (k.plc.estimate.recovery_time, dict(
        estimate=k.plc.KalmanFilter(k.sys, Q=k.q, R=1e-4, consistency_window=5).filter(
            k.X[:2, :60]), change_at=10, truth=k.X[2:, :60], rows=[2, 3]))),
    "estimation_accuracy": _b(lambda k: (k.plc.estimation_accuracy,
                                         dict(estimate=k.est, truth=k.est.states))),
    "filter_consistency": _b(lambda k: (k.plc.estimate.filter_consistency,
                                        dict(estimate=k.est, window=10))),
    "design_estimator": _b(lambda k: (k.plc.design_estimator,
                                      dict(snapshots=k.snap, n_sensors=2, delays=2, rank=4,
                                           spatial_rank=3, seed=0)), slow=True),
    "estimator_count_study": _b(lambda k: (k.plc.recipe.estimator_count_study,
                                           dict(snapshots=k.count_record(), k_values=[2, 3],
                                                delays=2, rank=4, spatial_rank=3)), slow=True),
    "observability_rank": _b(lambda k: (k.plc.estimate.observability_rank,
                                        dict(sys=k.sys_all, sensors=[0, 1]))),
    "observability_gramian": _b(lambda k: (k.plc.estimate.observability_gramian,
                                           dict(sys=k.sys_all, horizon=10, sensors=[0]))),
    "analyze_observability": _b(lambda k: (k.plc.estimate.analyze_observability,
                                           dict(sys=k.sys_all, sensors=[0, 1], Q=k.q, R=1e-4,
                                                horizon=10))),
    "compare_sensor_sets": _b(lambda k: (k.plc.estimate.compare_sensor_sets,
                                         dict(sys=k.sys_all, sensor_sets={"a": [0], "b": [1]},
                                              horizon=10))),
    "steady_state_covariance": _b(lambda k: (k.plc.estimate.steady_state_covariance,
                                             dict(sys=k.sys, Q=k.q, R=1e-4))),
    "select_sensors": _b(lambda k: (k.plc.select_sensors,
                                    dict(sys=k.sys_all, k=2, criterion="gramian", Q=k.q,
                                         R=1e-4, horizon=10)), slow=True),
    "select_sensors.cost": _b(lambda k: (k.plc.select_sensors,
                                         dict(sys=k.sys_all, k=2, criterion="gramian", Q=k.q,
                                              horizon=10, cost=k.np.array([1.0, 1.0, 2.0, 2.0]),
                                              budget=3.0)),
                              skip=("sys", "k", "criterion", "Q", "R", "positions", "forbidden",
                                    "min_spacing", "required", "error_weight", "basis",
                                    "horizon", "relaxation_rank", "solver", "n_random",
                                    "brute_force_limit", "seed")),
    "sensor_count_study": _b(lambda k: (k.plc.sensors.sensor_count_study,
                                        dict(sys=k.sys_all, k_values=[1, 2], Q=k.q, R=1e-4,
                                             n_steps=50)), slow=True),
    # ---------------------------------------------------------------- antinodes, motion
    "locate_antinodes": _b(lambda k: (k.plc.locate_antinodes,
                                      dict(field=k.field, x=k.model.node_positions))),
    "largest_antinode": _b(lambda k: (k.plc.antinode.largest_antinode,
                                      dict(antinodes=k.antinodes))),
    "nearest_antinode": _b(lambda k: (k.plc.nearest_antinode, dict(antinodes=k.antinodes,
                                                                   position=1.0))),
    "RobotLimits": _b(lambda k: (k.plc.RobotLimits, dict(v_max=0.5, a_max=1.0, j_max=10.0,
                                                         length=0.2))),
    "RobotLimits.stopping_distance": _b(lambda k: (k.limits.stopping_distance,
                                                   dict(velocity=0.3))),
    "free_interval": _b(lambda k: (k.plc.plan.free_interval, dict(position=1.0, limits=k.limits,
                                                             span_length=3.66,
                                                             obstacles=[(2.0, 2.2)]))),
    "plan_motion": _b(lambda k: (k.plc.plan_motion, dict(start=0.2, target=1.0,
                                                         limits=k.limits, span_length=3.66)),
                      skip=("method", "n_intervals", "max_iter", "objective", "duration")),
    "MotionPlanner": _b(lambda k: (k.plc.MotionPlanner, dict(limits=k.limits, span_length=3.66,
                                                             horizon=20))),
    "MotionPlanner.step": _b(lambda k: (k.planner.step, dict(state=(1.0, 0.0), target=1.5)),
                             slow=True),
    # ---------------------------------------------------------------- closed loop
    "parked_steady_state": _b(lambda k: (k.plc.simulation.parked_steady_state,
                                         dict(model=k.model, force=k.force, robot=k.mdr,
                                              positions=k.np.array([1.0, 2.0])))),
    "choose_parked_position": _b(lambda k: (k.plc.closed_loop.choose_parked_position,
                                            dict(model=k.model, field=k.snap.displacement,
                                                 dt=k.snap.dt, robot=k.mdr, start=1.0,
                                                 limits=k.limits)), slow=True),
    "run_closed_loop": _b(lambda k: (k.plc.run_closed_loop,
                                     dict(model=k.lab, force=k.force, robot=k.mdr,
                                          limits=k.limits, sensors=[3, 5, 7], n_elements=10,
                                          duration=0.6, calibration=0.3, seed=1)), slow=True),
    "PolicySettings": _b(lambda k: (k.plc.PolicySettings, {})),
    # The same call told a nominal span (design.md 4.7): its bad kinds on a Span (the row above
    # sweeps nominal from its default None); the other parameters are swept above.
    "run_closed_loop.nominal": _b(lambda k: (k.plc.run_closed_loop,
                                             dict(model=k.lab, force=k.force, robot=k.mdr,
                                                  limits=k.limits, sensors=[3, 5, 7],
                                                  n_elements=10, duration=0.6, calibration=0.3,
                                                  seed=1, nominal=k.lab)),
                                  slow=True, skip=_RUN_CLOSED_LOOP_PARAMETERS),
    # ---------------------------------------------------------------- severity
    "aeolian_severity": _b(lambda k: (k.plc.aeolian_severity,
                                      dict(span=k.plc.Span.at_rts_fraction(300.0, "drake", 0.2),
                                           wind_speeds=[2.0, 4.0]))),
    "catenary_check": _b(lambda k: (k.plc.severity.catenary_check,
                                    dict(span=k.plc.Span.at_rts_fraction(300.0, "drake", 0.2)))),
    "AtAntinode": _b(lambda k: (k.plc.fem.AtAntinode, dict(damper=k.mdr))),
    "ImpedanceDamper": _b(lambda k: (k.plc.fem.ImpedanceDamper,
                                     dict(position=1.0, frequencies=(5.0, 50.0),
                                          impedance=(10 + 1j, 20 + 2j)))),
    "damper_impedance": _b(lambda k: (k.plc.fem.damper_impedance, dict(damper=k.mdr,
                                                                   frequency=10.0))),
    "damper_power": _b(lambda k: (k.plc.severity.damper_power, dict(damper=k.mdr, span=k.lab,
                                                           amplitude=1e-3, frequency=20.0))),
    "harmonic_mean_position": _b(lambda k: (k.plc.severity.harmonic_mean_position,
                                            dict(span=k.plc.Span.at_rts_fraction(
                                                300.0, "drake", 0.2)))),
    "loop_length": _b(lambda k: (k.plc.severity.loop_length, dict(span=k.lab, frequency=20.0))),
    "robot_value": _b(lambda k: (k.plc.severity.robot_value,
                                 dict(span=k.plc.Span.at_rts_fraction(300.0, "drake", 0.2),
                                      damper=k.plc.MDR(1.0, 1.0), limits=k.limits,
                                      wind_speeds=[2.0, 4.0])), slow=True),
    "self_damping_power": _b(lambda k: (k.plc.severity.self_damping_power,
                                        dict(amplitude=1e-3, frequency=20.0,
                                             span=k.plc.Span.at_rts_fraction(300.0, "drake",
                                                                             0.2)))),
    "SelfDampingLaw": _b(lambda k: (k.plc.severity.SelfDampingLaw,
                                    dict(name="x", label="x", l=2.5, m=5.6, n=2.6, k=1e-10))),
    "standing_wave_shape": _b(lambda k: (k.plc.severity.standing_wave_shape,
                                         dict(span=k.lab, frequency=20.0, position=1.0))),
    "time_domain_check": _b(lambda k: (k.plc.severity.time_domain_check,
                                       dict(span=k.plc.Span.at_rts_fraction(50.0, "drake", 0.2),
                                            wind_speed=3.0, n_elements=60, settle=1.0)),
                            slow=True),
    "turbulence_factor": _b(lambda k: (k.plc.severity.turbulence_factor,
                                       dict(turbulence_intensity=0.1))),
    "wind_power": _b(lambda k: (k.plc.severity.wind_power, dict(amplitude=1e-3, frequency=20.0,
                                                       diameter=0.028))),
    "StrandLayer": _b(lambda k: (k.plc.severity.StrandLayer, dict(wires=16, wire_diameter=4.44e-3,
                                                         modulus=68.9e9, lay_ratio=12.0,
                                                         material="aluminium"))),
    "stranded_bending": _b(lambda k: (k.plc.severity.stranded_bending,
                                      dict(conductor=k.plc.conductors["aster570"],
                                           tension=40e3))),
    "FotiMartinelli": _b(lambda k: (k.plc.severity.FotiMartinelli,
                                    dict(ei_max=2155.0, limit_curvature_per_tension=0.1407
                                         / 185.3e3))),
    "WindDistribution": _b(lambda k: (k.plc.severity.WindDistribution, dict(kind="weibull"))),
    "WindDistribution.histogram": _b(lambda k: (k.plc.severity.WindDistribution.histogram,
                                                dict(edges=[0.0, 2.0, 4.0, 8.0],
                                                     density=[0.125, 0.25, 0.0625]))),
    "WindDistribution.probability_of": _b(lambda k: (k.wind.probability_of,
                                                     dict(wind_speeds=k.np.array([2.0, 4.0])))),
    "WindPowerCurve": _b(lambda k: (k.plc.severity.WindPowerCurve,
                                    dict(name="x", label="x", source="s",
                                         amplitudes=(0.1, 0.5, 1.0),
                                         powers=(1.0, 5.0, 9.0)))),
    "tension_at_temperature": _b(lambda k: (k.plc.tension_at_temperature,
                                            dict(span=k.plc.Span.at_rts_fraction(300.0, "drake",
                                                                                 0.2),
                                                 temperature=40.0))),
    "WindRecord": _b(lambda k: (k.plc.WindRecord,
                                dict(time=k.np.array([0.0, 600.0, 1200.0]),
                                     wind_speed=k.np.array([3.0, 4.0, 2.0]),
                                     direction=k.np.array([90.0, 80.0, 85.0]),
                                     temperature=k.np.array([12.0, 11.5, 11.0])))),
    "WindRecord.from_csv": _b(lambda k: (k.plc.WindRecord.from_csv, dict(path=k.wind_csv()))),
    "rainflow_count": _b(lambda k: (k.plc.severity.rainflow_count,
                                    dict(signal=k.np.sin(k.np.linspace(0.0, 20.0, 200))))),
    "rainflow_damage": _b(lambda k: (k.plc.severity.rainflow_damage,
                                     dict(stress=1e7 * k.np.sin(k.np.linspace(0.0, 20.0, 200))))),
    "fatigue_over_record": _b(lambda k: (k.plc.fatigue_over_record,
                                         dict(span=k.plc.Span.at_rts_fraction(300.0, "drake",
                                                                              0.2),
                                              record=k.plc.WindRecord(
                                                  k.np.array([0.0, 600.0, 1200.0]),
                                                  k.np.array([3.0, 4.0, 2.0]),
                                                  k.np.array([90.0, 80.0, 85.0]),
                                                  k.np.array([12.0, 11.5, 11.0])),
                                              damper=k.plc.MDR(1.0, 1.0),
                                              limits=k.limits))),
    "estimate_clamp_strain": _b(lambda k: (k.plc.severity.estimate_clamp_strain,
                                           dict(design=k.clamp_design()[0],
                                                measurements=k.clamp_design()[1],
                                                span=k.plc.Span.at_rts_fraction(300.0, "drake",
                                                                                0.2),
                                                positions=k.clamp_design()[2], discard=100)),
                                slow=True),
    "calibrate_span": _b(lambda k: (k.plc.calibrate_span,
                                    dict(record=k.ringing_record(), nominal=k.lab)), slow=True),
    # ---------------------------------------------------------------- records, scenarios
    "Record": _b(lambda k: (k.plc.Record, dict(t=[0.0, 0.001, 0.002], positions=[1.0],
                                               values=[[0.0, 1e-3, 2e-3]]))),
    "save_record": _b(lambda k: (k.plc.save_record,
                                 dict(path=str(k.tmp / "rec"),
                                      record=k.plc.Record([0.0, 0.5, 1.0], [1.0],
                                                          [[0.0, 1e-3, 2e-3]])))),
    "load_record": _b(lambda k: (k.plc.load_record, dict(path=k.record_csv()))),
    "shipped_scenarios": _b(lambda k: (k.plc.scenario.shipped_scenarios, {})),
    "load_scenario": _b(lambda k: (k.plc.load_scenario, dict(path="paper-lab-20"))),
    "Scenario": _b(lambda k: (k.plc.Scenario, {})),
    "run_scenario": _b(lambda k: (k.plc.run_scenario, dict(scenario="paper-lab-20")), slow=True),
    # The [truth] section's one home (its keys are swept by test_schema_and_cli_sweep).
    "true_span": _b(lambda k: (k.plc.scenario.true_span,
                               dict(scenario=k.truth_scenario(), nominal=None))),
    "true_model": _b(lambda k: (k.plc.scenario.true_model,
                                dict(scenario=k.truth_scenario(), nominal=k.model))),
    # ---------------------------------------------------------------- studies
    "parameter_grid": _b(lambda k: (k.plc.parameter_grid, dict(a=[1.0, 2.0], b=["x"]))),
    "point_seed": _b(lambda k: (k.plc.studies.point_seed, dict(seed=3, point={"a": 1.0}))),
    "run_study": _b(lambda k: (k.plc.run_study, dict(func=_study_point, grid=[{"a": 1.0}],
                                                     progress=False))),
    "StudyResult": _b(lambda k: (k.plc.StudyResult, dict(parameters=({"a": 1.0},),
                                                         results=({"b": 2.0},)))),
    "StudyResult.column": _b(lambda k: (k.study.column, dict(name="b"))),
    "StudyResult.to_json": _b(lambda k: (k.study.to_json, dict(path=str(k.tmp / "s.json")))),
    "StudyResult.to_csv": _b(lambda k: (k.study.to_csv, dict(path=str(k.tmp / "s.csv")))),
    "StudyResult.from_json": _b(lambda k: (k.plc.StudyResult.from_json,
                                           dict(path=str(k.study_file)))),
}

# Result classes are built by the library, not by users (test_reliability's list): no baseline.
RESULTS = {"Accuracy", "AlphaCurve", "Antinode", "Baseline", "ClosedLoopResult", "Consistency",
           "DampingReport", "DMDModel", "EstimatorDesign", "Estimate", "MPCStep",
           "ObservabilityReport", "SensorCountStudy", "SensorSelection", "SensorSetComparison",
           "Snapshots", "StabilityReport", "Trajectory", "CatenaryCheck", "RobotValue",
           "SeverityResult", "TimeDomainCheck", "Choice", "ParkedSteadyState", "ModalBasis",
           "Coverage", "FatigueOverRecord", "RainflowCount", "RecordDamage",
           "ClampStrainEstimate", "ScenarioResult", "EstimatorCountStudy", "StrandedBending",
           "SpanCalibration", "Recovery"}
NOT_CALLABLE = {"conductors", "SELF_DAMPING_LAWS", "WIND_POWER_CURVES"}  # mappings


# ============================================================================ bad values
_PATH_PARAMETERS = {"path"}
_NO_VALUE = object()


def _is_number(value) -> bool:
    import numbers

    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def kinds_for(parameter: str, value) -> list[str]:
    """The bad-value kinds tried on a parameter whose valid (baseline) value is ``value``."""
    import numbers

    import numpy as np

    if parameter in _PATH_PARAMETERS:
        return ["folder", "fifo", "binary", "missing_dir", "empty_text", "number"]
    if isinstance(value, bool | np.bool_):
        return ["text_flag", "int_flag", "none"]
    if isinstance(value, numbers.Integral):
        return ["nan", "inf", "negative", "zero", "huge_int", "float_int", "text", "bool",
                "none"]
    if _is_number(value):
        return ["nan", "inf", "-inf", "negative", "zero", "huge", "tiny", "text", "bool",
                "none", "complex"]
    if value is None:
        return ["nan", "inf", "negative", "zero", "text", "bool", "object"]
    if isinstance(value, str):
        return ["empty_text", "unknown_text", "number", "none"]
    if isinstance(value, complex):
        return ["nan", "text", "bool"]
    if isinstance(value, np.ndarray | list | tuple) and _numeric_sequence(value):
        kinds = ["nan_entry", "inf_entry", "empty", "extra_axis", "scalar", "bool_array",
                 "text_array", "negated", "none"]
        if np.ndim(value) == 2 and np.shape(value)[0] != np.shape(value)[1]:
            kinds.append("transposed")
        if np.ndim(value) >= 1 and np.size(value) > 1:
            kinds.append("reversed")
        return kinds
    if isinstance(value, dict):
        return ["empty_mapping", "text", "none"]
    if isinstance(value, list | tuple):
        return ["empty", "text", "none", "number"]
    return ["text", "number", "none"]   # an object (Span, LineModel, StateSpace, ...)


def _numeric_sequence(value) -> bool:
    import numpy as np

    try:
        array = np.asarray(value)
    except (TypeError, ValueError):
        return False
    return array.dtype.kind in "iufc" and array.size > 0


def bad_value(kind: str, value, k: Kit):
    """The bad value of ``kind`` for a parameter whose baseline value is ``value``."""
    np = k.np
    scale = abs(value) if _is_number(value) and value != 0 else 1.0
    simple = {
        "nan": math.nan, "inf": math.inf, "-inf": -math.inf, "negative": -scale, "zero": 0,
        "huge": 1e300, "tiny": 1e-300, "text": "1.0", "bool": True, "none": None,
        "complex": complex(scale, 1.0), "huge_int": 10**15, "float_int": 2.0,
        "text_flag": "no", "int_flag": 1, "object": object(), "empty_text": "",
        "unknown_text": "no-such-choice", "number": 1.0, "empty_mapping": {},
    }
    if kind == "negative" and isinstance(value, int) and not isinstance(value, bool):
        return -max(abs(value), 1)
    if kind in simple:
        return simple[kind]
    if kind in ("folder", "fifo", "binary", "missing_dir"):
        return k.path(kind)
    if not _numeric_sequence(value):           # a list of objects (antinodes, grid points)
        if kind == "empty":
            return type(value)() if isinstance(value, list | tuple) else []
        raise KeyError(kind)
    array = np.array(value, dtype=complex if np.iscomplexobj(value) else float)
    as_list = not isinstance(value, np.ndarray)

    def out(a):
        return a.tolist() if as_list else a

    if kind == "nan_entry":
        a = array.copy()
        a.flat[-1] = np.nan
        return out(a)
    if kind == "inf_entry":
        a = array.copy()
        a.flat[0] = np.inf
        return out(a)
    if kind == "empty":
        return out(np.zeros((0,) * max(array.ndim, 1)))
    if kind == "extra_axis":
        return out(array[None, ...])
    if kind == "scalar":
        return float(array.flat[0].real)
    if kind == "bool_array":
        return out(array != 0)
    if kind == "text_array":
        return out(array.astype(str))
    if kind == "negated":
        return out(-array)
    if kind == "transposed":
        return out(array.T)
    if kind == "reversed":
        return out(array[::-1] if array.ndim == 1 else array[:, ::-1])
    raise KeyError(kind)


# ============================================================================ cases
def bound_arguments(name: str, k: Kit):
    """``(callable, ordered {parameter: baseline value})`` for a name (defaults filled in)."""
    fn, given = BASELINES[name].make(k)
    signature = inspect.signature(fn)
    values = {}
    for parameter in signature.parameters.values():
        if parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
            continue
        if parameter.name in given:
            values[parameter.name] = given[parameter.name]
        elif parameter.default is not parameter.empty:
            values[parameter.name] = parameter.default
        else:
            raise AssertionError(f"baseline of {name} lacks {parameter.name}")
    # **kwargs entries (parameter_grid axes), in the baseline's order: a set's order changes with
    # the hash seed, and parallel test workers must collect the same cases in the same order
    extra = [parameter for parameter in given if parameter not in values]
    for parameter in extra:
        values[parameter] = given[parameter]
    return fn, values


def available(k: Kit) -> list[str]:
    """The baselines whose callable this version of the package has (a name being added in a
    working tree may not be committed yet; its cases appear once it is)."""
    names = []
    for name in BASELINES:
        try:
            BASELINES[name].make(k)
        except AttributeError:
            continue
        names.append(name)
    return names


def case_ids(k: Kit) -> list[str]:
    """Every case id ``name::parameter::kind`` (baselines included as ``name::-::baseline``)."""
    ids = []
    for name in available(k):
        _, values = bound_arguments(name, k)
        ids.append(f"{name}::-::baseline")
        for parameter, value in values.items():
            if parameter in BASELINES[name].skip:
                continue
            ids.extend(f"{name}::{parameter}::{kind}" for kind in kinds_for(parameter, value))
    return ids


def run_case(case: str) -> dict:
    """Run one case in this process; return its outcome record."""
    import numpy as np

    from powerline_control.errors import PowerlineControlError

    name, parameter, kind = case.split("::")
    k = kit()
    fn, values = bound_arguments(name, k)
    if kind != "baseline":
        values[parameter] = bad_value(kind, values[parameter], k)
    record = {"case": case}
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with np.errstate(all="warn"):
                result = fn(**values)
        except MemoryError as exc:
            record.update(outcome="memory", error="MemoryError", message=str(exc)[:300])
        except PowerlineControlError as exc:
            message = str(exc)
            if isinstance(exc, ValueError | TypeError):
                text = message.lower()
                named = (parameter == "-" or parameter.lower() in text
                         or (isinstance(values.get(parameter), str) and values[parameter]
                             and values[parameter].lower() in text))   # a path, by its value
                # A relation between two parameters may be reported on the other one.
                related = any(f"'{other.lower()}'" in text for other in values)
                outcome = "own" if named else "related" if related else "unnamed"
            else:
                outcome = "runtime"
            record.update(outcome=outcome, error=type(exc).__name__, message=message[:300])
        except Exception as exc:  # noqa: BLE001 - classifying every other exception is the point
            tb = traceback.extract_tb(exc.__traceback__)
            where = f"{Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else "?"
            record.update(outcome="raw", error=type(exc).__name__,
                          message=f"{str(exc)[:250]} [{where}]")
        else:
            record.update(outcome="accepted", result=repr(result)[:120],
                          nonfinite=_has_nonfinite(result))
    record["seconds"] = time.perf_counter() - start
    record["warnings"] = sorted({f"{w.category.__name__}: {str(w.message)[:80]}"
                                 for w in caught})
    return record


def _has_nonfinite(value, depth: int = 0) -> bool:
    """Whether a result holds a NaN or an infinity (numbers, arrays, dataclass fields, ...)."""
    import dataclasses
    import numbers

    import numpy as np

    if depth > 4:
        return False
    if isinstance(value, bool | str | type(None)):
        return False
    if isinstance(value, numbers.Number):
        return not np.isfinite(complex(value))
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "fc" and not bool(np.all(np.isfinite(value)))
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return any(_has_nonfinite(getattr(value, f.name), depth + 1)
                   for f in dataclasses.fields(value))
    if isinstance(value, dict):
        return any(_has_nonfinite(v, depth + 1) for v in list(value.values())[:1000])
    if isinstance(value, list | tuple):
        return any(_has_nonfinite(v, depth + 1) for v in value[:1000])
    return False


# ============================================================================ worker
def _worker() -> None:
    """Read case ids from stdin, one a line; write one JSON record a line to stdout."""
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (WORKER_MEMORY_LIMIT, WORKER_MEMORY_LIMIT))
    out = sys.stdout
    sys.stdout = sys.stderr   # stray prints must not corrupt the protocol
    kit()
    out.write(json.dumps({"ready": True}) + "\n")
    out.flush()
    for line in sys.stdin:
        case = line.strip()
        if not case:
            continue
        try:
            record = run_case(case)
        except BaseException as exc:  # noqa: BLE001 - the harness itself failed on this case
            record = {"case": case, "outcome": "harness", "error": type(exc).__name__,
                      "message": str(exc)[:300], "seconds": 0.0, "warnings": []}
        out.write(json.dumps(record, default=str) + "\n")
        out.flush()


def worker_environment() -> dict:
    env = dict(os.environ)
    env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1",
               POWERLINE_CONTROL_MEMORY_BUDGET=str(WORKER_BUDGET), MPLBACKEND="Agg")
    return env


def guarded(source: str, *, timeout: float = 120.0, memory: int = WORKER_MEMORY_LIMIT) -> str:
    """Run ``source`` in a fresh interpreter under an address-space limit; its stdout.

    For regression tests of the allocations a budget must refuse: on the old code the call would
    have allocated gigabytes (a MemoryError here, not a swapping machine) or run for minutes (the
    timeout, a hang guard). Raises ``AssertionError`` with stderr when the script fails.
    """
    import resource
    import subprocess

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    done = subprocess.run([sys.executable, "-c", source], capture_output=True, text=True,
                          timeout=timeout, preexec_fn=limit, env=worker_environment())
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


# ============================================================================ parent side
def run_all(cases: list[str], *, workers: int = 2, timeout: float = 60.0) -> dict[str, dict]:
    """Run ``cases`` over ``workers`` guarded worker processes; ``{case: record}``.

    A worker that does not answer a case within ``timeout`` seconds (a hang guard, generous:
    the slowest valid case takes about a second) is killed, the case recorded as ``hang`` and
    a fresh worker takes the next case; a worker that dies records ``crash``.
    """
    import queue
    import selectors
    import signal
    import subprocess
    import threading

    todo: queue.Queue = queue.Queue()
    for case in cases:
        todo.put(case)
    results: dict[str, dict] = {}
    lock = threading.Lock()

    def start():
        process = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), "worker"], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
            env=worker_environment(), start_new_session=True)
        line = process.stdout.readline()
        if not line:
            raise RuntimeError("a sweep worker failed to start")
        return process

    def stop(process):
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        process.wait()
        for stream in (process.stdin, process.stdout):
            try:
                stream.close()
            except OSError:   # a pipe to a killed worker
                pass

    def serve():
        process = start()
        try:
            while True:
                try:
                    case = todo.get_nowait()
                except queue.Empty:
                    return
                process.stdin.write(case + "\n")
                process.stdin.flush()
                selector = selectors.DefaultSelector()
                selector.register(process.stdout, selectors.EVENT_READ)
                ready = selector.select(timeout)
                selector.close()
                line = process.stdout.readline() if ready else ""
                if line:
                    record = json.loads(line)
                else:
                    hung = process.poll() is None
                    stop(process)
                    record = {"case": case, "outcome": "hang" if hung else "crash",
                              "error": "", "message": f"no answer in {timeout:g} s"
                              if hung else f"worker exit {process.returncode}",
                              "seconds": timeout if hung else 0.0, "warnings": []}
                    process = start()
                with lock:
                    results[case] = record
        finally:
            stop(process)

    threads = [threading.Thread(target=serve) for _ in range(workers)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return results


if __name__ == "__main__":
    if sys.argv[1:] == ["worker"]:
        _worker()
    else:   # run a few cases here and print them: python tests/sweep_cases.py 'fit_dmd::dt::nan'
        for case in sys.argv[1:]:
            print(json.dumps(run_case(case), default=str))
