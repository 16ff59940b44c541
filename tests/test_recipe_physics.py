"""Tests of the recipe's physics candidate (recipe/physics.py) and identify/span_model.py.

Independent truths: the pinned taut beam's closed-form natural frequencies and sine mode shapes
(design.md 4.1) for the model that :func:`span_model` writes down, and FE simulations of new runs
(the truth's tension drawn off the nominal; the estimator is told the nominal only) for the
accuracy and the choice of the candidate.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import CalibrationWarning, ExcitationWarning, InputError
from powerline_control.identify import SpanModel, span_model

sys.path.insert(0, str(Path(__file__).resolve().parent))
import lockin_family as family  # noqa: E402


@pytest.fixture(scope="module")
def lab_calibration():
    """The lab span, its tension 4 % above the nominal, calibrated from three sensors."""
    nominal = plc.Span.paper_lab()
    truth = plc.LineModel(plc.Span(nominal.length, 1.04 * nominal.tension, nominal.conductor),
                          40, damping=plc.ModalDamping(0.005))
    snap = plc.simulate(truth, plc.RandomForce(0.5, 1.1, bandwidth=150.0, seed=1),
                        duration=10.0, dt=1e-3, noise_fraction=0.01, seed=2)
    rec = plc.Record(snap.t, snap.x[[7, 16, 29]], snap.displacement[[7, 16, 29]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CalibrationWarning)
        return plc.calibrate_span(rec, nominal)


def test_span_model_holds_the_calibrated_spans_modes(lab_calibration):
    cal = lab_calibration
    x = np.linspace(0.0, cal.span.length, 31)
    model = span_model(cal, x, 1e-3, n_pairs=100, process_noise=1e-12, modes_per_side=1)
    assert isinstance(model, SpanModel) and model.calibration is cal
    n = model.mode_numbers
    # Each line's nearest mode and one on either side, numbered from the fundamental.
    assert np.all(np.diff(n) == 1) and n.size == model.n_lines
    # Closed form of the pinned taut beam (design.md 4.1) at the calibrated tension and EI;
    # the mesh is accurate to 1e-4 (span_model.MESH_TOLERANCE), so 5e-4 leaves room.
    expected = cal.span.pinned_frequencies(int(n.max()))[n - 1]
    assert np.allclose(model.line_frequencies, expected, rtol=5e-4)
    # Shapes: sin(n pi x / L) up to sign and scale (unit peak); the nodes are 31 points.
    for j, mode in enumerate(n):
        exact = np.sin(mode * np.pi * x / cal.span.length)
        shape = model.line_shapes[:, j]
        fit = shape @ exact / (exact @ exact)
        assert np.max(np.abs(shape - fit * exact)) < 1e-3
    # One radius from the damping ratio at the modes' mean frequency.
    omega_c = np.mean(2 * np.pi * model.line_frequencies)
    assert model.radius == pytest.approx(np.exp(-1e-3 * omega_c * 1e-3), rel=1e-12)
    assert model.describe().startswith("physics model of the calibrated span (3.66 m")


def test_lock_in_noise_drives_the_mode_whose_wavelength_the_wind_has(lab_calibration):
    """With ``lock_in`` at a mode's natural frequency, the lift (sin(k x), cos(k x) with k the
    span's wavenumber there) has its largest generalised force on that mode: on a pinned span
    the sine modes are orthogonal and sin(n pi x / L) against sin(k x) peaks at k = n pi / L.
    The covariance's trace per mode is the process noise, and it has at most two directions
    per wavenumber pattern."""
    cal = lab_calibration
    x = np.linspace(0.0, cal.span.length, 121)
    base = span_model(cal, x, 1e-3, n_pairs=100, process_noise=2e-12, modes_per_side=3)
    j = int(np.flatnonzero(base.mode_numbers == 4)[0])
    model = span_model(cal, x, 1e-3, n_pairs=100, process_noise=2e-12, modes_per_side=3,
                       lock_in=float(base.line_frequencies[j]))
    r = model.n_lines
    block = np.asarray(model.residual_covariance)[:r, :r]
    assert np.trace(block) == pytest.approx(2e-12 * r, rel=1e-9)
    # back to the modes' own amplitudes a = R^-1 b (the line coordinates are b = Q^T x)
    _, upper = np.linalg.qr(model.line_shapes)
    inv = np.linalg.inv(upper)
    amplitudes = inv @ block @ inv.T
    assert int(np.argmax(np.diag(amplitudes))) == j
    # unchanged everywhere but the current line block
    rest = np.asarray(model.residual_covariance).copy()
    rest[:r, :r] = 0.0
    base_rest = np.asarray(base.residual_covariance).copy()
    base_rest[:r, :r] = 0.0
    assert np.array_equal(rest, base_rest)


@pytest.mark.parametrize("kwargs, name", [
    ({"lock_in": -3.0}, "lock_in"),
    ({"calibration": "cal"}, "calibration"),
    ({"positions": [0.0, 99.0]}, "positions"),
    ({"modes_per_side": -1}, "modes_per_side"),
    ({"damping_ratio": 0.7}, "damping_ratio"),
    ({"process_noise": -1.0}, "process_noise"),
])
def test_span_model_names_bad_input(lab_calibration, kwargs, name):
    args = {"calibration": lab_calibration, "positions": np.linspace(0, 3.66, 5), "dt": 1e-3,
            "n_pairs": 10, "process_noise": 0.0} | kwargs
    calibration, positions, dt = args.pop("calibration"), args.pop("positions"), args.pop("dt")
    with pytest.raises(InputError, match=name):
        span_model(calibration, positions, dt, **args)


@pytest.fixture(scope="module")
def lab_broadband():
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    return plc.simulate(model, plc.RandomForce(1.0, 1.3, 90.0, seed=4), duration=4.0, dt=1e-3,
                        noise_fraction=0.01, seed=2)


@pytest.mark.parametrize("kwargs, name", [
    ({"bc": "clamped"}, "'bc'"),
    ({"method": "physics"}, "'nominal'"),
    ({"nominal": 3.66}, "'nominal'"),
    ({"nominal": plc.LineModel(plc.Span.paper_lab(), 10), "bc": "pinned"}, "'bc'"),
])
def test_design_estimator_names_a_bad_nominal(lab_broadband, kwargs, name):
    with pytest.raises(InputError, match=name):
        plc.design_estimator(lab_broadband, n_sensors=3, delays=4, rank=12, seed=0, **kwargs)


def test_broadband_lab_record_keeps_the_dmd_model(lab_broadband):
    """Told the nominal lab span, the recipe still picks DMD on a broadband record: many lines,
    not one tone, and DMD's held-out error is the smaller (the physics candidate's modes near
    the calibrated lines score worse there)."""
    design = plc.design_estimator(lab_broadband, n_sensors=3, delays=4, rank=12, seed=0,
                                  nominal=plc.Span.paper_lab())
    assert design.excitation.method == "dmd"
    assert not isinstance(design.model, SpanModel)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(family.CASES))
def test_lock_in_record_chooses_the_physics_model_and_estimates_a_faster_wind(name):
    """Two real spans the recipe was not tuned on (Oxlip 220 m pinned, Condor 180 m
    clamped; the truth's tension drawn off the nominal, the estimator told the nominal): trained
    on 20 s of wind in lock-in, tested on the same wind 1 % faster, against the noise-free
    simulation. Measured (docs/validation/physics_candidate.md, seed 1): today's recipe 12.4 %
    and 15.1 % at the unmeasured nodes, sigma 0.02x and 0.01x the actual error; with the nominal
    the physics model is chosen, 2.8 % and 2.4 %, sigma 0.55x and 0.59x. The bounds leave about
    2x on the error (5 % is the target) and cover the sigma ratio it measured."""
    nominal, bc, model, wind = family.draw(name, 1)
    train, test = family.records(model, wind, 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        design = plc.design_estimator(train, n_sensors=5, seed=0, nominal=nominal, bc=bc)
    assert design.excitation.method == "physics" and isinstance(design.model, SpanModel)
    error, ratio = family.judge(design, test)
    print(f"{name}: error {error:.2%}, sigma/actual {ratio:.2f}")
    assert error < 0.05
    assert 0.35 < ratio < 2.0


def test_a_layout_on_the_standing_waves_nodes_is_moved_to_its_loops():
    """Five sensors evenly spread over the moving nodes of a pinned span sit near multiples of
    L / 6: nodes of mode 36 (sin(36 pi x / L) = 0 there). The comparison's layout moves each to
    the node of largest RMS nearby: an antinode, |sin| within the mesh's step of 1; a layout
    that sees the wave is kept."""
    from powerline_control.recipe.physics import _scoring_layout

    length, n_nodes = 220.0, 433
    x = np.linspace(0.0, length, n_nodes)
    t = np.arange(3000) * 2e-3
    candidates = np.arange(1, n_nodes - 1)      # the supports do not move
    # the recipe's provisional layout: evenly spread over the moving nodes
    layout = candidates[np.linspace(0, candidates.size - 1, 7).round().astype(int)[1:-1]]

    def record(mode):
        return np.outer(np.sin(mode * np.pi * x / length), np.cos(2 * np.pi * 8.8 * t))

    # blind: three sensors on nodes of the wave, two a quarter of a loop off them (the mesh's
    # nodes do not fall on L / 6 exactly), under a tenth of the wave's mean square (1/2)
    assert np.mean(np.sin(36 * np.pi * x[layout] / length) ** 2) < 0.05
    moved = _scoring_layout(record(36), layout, candidates)
    assert moved.size == 5
    # the mesh step (0.51 m) against a loop of 6.1 m: |sin| >= cos(pi * 0.51 / 6.1 / 2) = 0.991
    assert np.abs(np.sin(36 * np.pi * x[moved] / length)).min() > 0.99
    assert np.array_equal(_scoring_layout(record(35), layout, candidates), layout)


def test_a_span_model_is_refused_by_save_model_before_any_file_is_written(lab_calibration,
                                                                          tmp_path):
    # Its lock-in noise has no place in the file format: a file written anyway would be
    # refused as corrupted when read back, so nothing is written.
    model = span_model(lab_calibration, np.linspace(0.0, lab_calibration.span.length, 31),
                       1e-3, n_pairs=100, process_noise=1e-12, modes_per_side=1)
    with pytest.raises(InputError, match="SpanModel"):
        plc.save_model(tmp_path / "span.npz", model)
    assert not any(tmp_path.iterdir())


def test_a_physics_design_says_what_it_is(lab_broadband):
    # method='physics' forces the candidate; its summary and message name the calibrated span,
    # not a DMD fit's alpha and delays.
    design = plc.design_estimator(lab_broadband, n_sensors=3, delays=4, rank=12, seed=0,
                                  nominal=plc.Span.paper_lab(), method="physics")
    assert isinstance(design.model, SpanModel) and design.excitation.method == "physics"
    text = design.summary()
    assert "physics model of the calibrated span" in text and "time-delay DMD" not in text
    assert "physics model" in design.excitation.message
