"""The oscillator model of narrowband records as its own type.

Independent truths: the eigenvalues of a two-step recursion per line in closed form, its free
response rho^k cos(omega k dt) and the same recursion run by hand; a file written the way the
previous release wrote it; the DMDModel-typed build of the same model through the same recipe.
"""

from __future__ import annotations

import dataclasses
import io
import json
import warnings
import zipfile

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import FileFormatError
from powerline_control.identify import DMDModel, OscillatorModel

RHO = 1 - 1e-6
DT = 1e-3
FREQS = np.array([6.5, 14.25, 31.0])


def _shapes(n: int, r: int, seed: int) -> np.ndarray:
    """r random independent nodal shapes (independent of the model's own construction)."""
    return np.random.default_rng(seed).standard_normal((n, r))


def _unseen(shapes: np.ndarray, count: int, seed: int) -> np.ndarray:
    """count orthonormal directions orthogonal to the shapes' span (complete, then drop)."""
    n, r = shapes.shape
    full = np.hstack([shapes, np.random.default_rng(seed).standard_normal((n, count))])
    q, _ = np.linalg.qr(full)
    return q[:, r:r + count]


@pytest.fixture(scope="module")
def built():
    shapes = _shapes(9, FREQS.size, seed=1)
    return OscillatorModel.from_lines(FREQS, shapes, DT, n_pairs=500, process_noise=1e-10,
                                      unseen=_unseen(shapes, 2, seed=2), unseen_noise=1e-8)


# ------------------------------------------------------------------------------ the spectrum


def test_eigenvalues_are_rho_exp_pm_i_omega_dt_per_line_and_zero_per_unseen_state(built):
    eig = np.linalg.eigvals(np.asarray(built.A))       # independent of the model's own eig
    expected = np.concatenate([RHO * np.exp(1j * 2 * np.pi * FREQS * DT),
                               RHO * np.exp(-1j * 2 * np.pi * FREQS * DT), np.zeros(2)])
    assert eig.size == expected.size == built.n_states == 2 * 3 + 2
    for value in expected:                            # a matching, one for one
        j = int(np.argmin(np.abs(eig - value)))
        assert abs(eig[j] - value) < 1e-9
        eig = np.delete(eig, j)
    assert built.is_stable and built.spectral_radius == pytest.approx(RHO, abs=1e-12)


def test_free_response_of_one_line_is_the_hand_recursion_and_rho_k_cos(built):
    f, dt, n_steps = 12.0, DT, 400
    shape = np.array([0.3, 1.0, -0.5, 0.8])
    model = OscillatorModel.from_lines([f], shape[:, None], dt, n_pairs=100, process_noise=0.0)
    w = 2 * np.pi * f * dt
    # a_k = rho^k cos(k w) solves a_{k+1} = 2 rho cos(w) a_k - rho^2 a_{k-1}: start at k = -1, 0
    window = np.column_stack([np.cos(-w) / RHO * shape, shape])
    run = model.predict(window, n_steps)
    a = [np.cos(-w) / RHO, 1.0]
    for _ in range(n_steps):
        a.append(2 * RHO * np.cos(w) * a[-1] - RHO**2 * a[-2])
    hand = np.outer(shape, a[2:])
    k = np.arange(1, n_steps + 1)
    closed = np.outer(shape, RHO**k * np.cos(w * k))
    np.testing.assert_allclose(run, hand, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run, closed, rtol=0, atol=1e-11)


def test_fields_carry_what_the_model_is(built):
    assert built.alpha == 0.0 and built.delays == 2 and built.B is None
    np.testing.assert_array_equal(built.line_frequencies, FREQS)
    assert built.n_lines == 3 and built.n_unseen == 2 and built.radius == RHO
    # field_map is the orthonormal line basis, zeros for the lagged coordinates, then unseen
    q = built.field_map[:, :3]
    np.testing.assert_allclose(q.T @ q, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(q @ (q.T @ built.line_shapes), built.line_shapes, atol=1e-12)
    assert not np.any(built.field_map[:, 3:6])
    np.testing.assert_array_equal(built.field_map[:, 6:], built.unseen)
    np.testing.assert_array_equal(np.diag(built.residual_covariance),
                                  [1e-10] * 3 + [0.0] * 3 + [1e-8] * 2)
    assert built.state_names[:1] + built.state_names[-1:] == ["line0", "unseen1"]


def test_text_says_oscillator_model_and_its_lines_not_dmd_alpha_or_delays(built):
    head = "scillator model, 3 lines at 6.5, 14.25 and 31 Hz"
    texts = {"repr": repr(built), "summary": built.summary(),
             "stability": built.stability_report(warn=False).message,
             "damping": built.damping_report().message}
    for name, text in texts.items():
        assert head in text, name
        assert "alpha" not in text and "delay" not in text, name
    assert not built.damping_report().trusted.any()  # assumed undamped, never identified
    with pytest.warns(plc.IllConditionedWarning, match="assumed, not identified"):
        built.damping_report(warn=True)


@pytest.mark.parametrize(("kwargs", "fragment"), [
    ({"frequencies": [1.0, 2.0]}, "'shapes'"),
    ({"frequencies": [600.0]}, "'frequencies'"),
    ({"shapes": [[1.0, 2.0], [2.0, 4.0]], "frequencies": [1.0, 2.0]}, "linearly independent"),
    ({"radius": 1.5}, "'radius'"),
    ({"process_noise": -1.0}, "'process_noise'"),
    ({"unseen": np.ones((3, 1))}, "'unseen'"),
    # The documented preconditions (no line; unseen neither unit nor orthogonal)
    ({"frequencies": [], "shapes": np.zeros((2, 0))}, "at least one line"),
    ({"unseen": [[2.0], [-1.0]]}, r"'unseen'.*\|U\^T U - I\| = 4"),   # orthogonal, norm sqrt 5
    ({"unseen": [[1.0], [0.0]]}, r"'unseen'.*\|Q\^T U\| = 0.894"),   # unit, not orthogonal
])
def test_from_lines_refuses_bad_arguments_naming_them(kwargs, fragment):
    args = {"frequencies": [5.0], "shapes": [[1.0], [0.5]], "dt": DT, "n_pairs": 10,
            "process_noise": 0.0, **kwargs}
    with pytest.raises(plc.InputError, match=fragment):
        OscillatorModel.from_lines(args.pop("frequencies"), args.pop("shapes"), args.pop("dt"),
                                   **args)


# ------------------------------------------------------------------------------- save / load


def _assert_same(loaded, model):
    assert type(loaded) is type(model)
    for f in dataclasses.fields(model):
        ours, theirs = getattr(model, f.name), getattr(loaded, f.name)
        if isinstance(ours, np.ndarray):
            np.testing.assert_array_equal(theirs, ours, err_msg=f.name)
        else:
            assert theirs == ours, f.name


def test_save_load_round_trip_keeps_type_and_arrays(built, tmp_path):
    plc.save_model(tmp_path / "osc.npz", built)
    with np.load(tmp_path / "osc.npz", allow_pickle=False) as archive:
        header = json.loads(str(archive["__metadata__"]))
    assert header["format"] == "powerline_control.OscillatorModel"
    assert header["fields"]["n_lines"] == 3
    _assert_same(plc.load_model(tmp_path / "osc.npz"), built)


def _as_dmd(model: OscillatorModel) -> DMDModel:
    """The same model typed as the previous release built it (DMDModel fields only)."""
    return DMDModel(**{f.name: getattr(model, f.name) for f in dataclasses.fields(DMDModel)})


def test_a_file_written_as_the_previous_release_did_loads_as_a_dmd_model(built, tmp_path):
    old = _as_dmd(built)
    # The previous release's writer, spelled out: DMDModel entries and this exact header.
    fields = {"dt": old.dt, "alpha": 0.0, "alpha_relative": 0.0, "delays": 2,
              "rank": old.rank, "n_nodes": old.n_nodes, "n_pairs": old.n_pairs,
              "has_B": False, "has_basis": True, "has_regressor_gram": False}
    header = {"format": "powerline_control.DMDModel", "version": 1, "fields": fields}
    path = tmp_path / "old.npz"
    np.savez(path, A=old.A, field_map=old.field_map, residual_covariance=old.residual_covariance,
             initial_state=old.initial_state, basis=old.basis,
             __metadata__=np.array(json.dumps(header)))
    loaded = plc.load_model(path)
    _assert_same(loaded, old)
    assert type(loaded) is DMDModel


# Forged or corrupted OscillatorModel files: each refused with a message naming the field.
def _entries(model, tmp_path) -> dict[str, bytes]:
    plc.save_model(tmp_path / "good.npz", model)
    with zipfile.ZipFile(tmp_path / "good.npz") as archive:
        return {info.filename: archive.read(info) for info in archive.infolist()}


def _npy(array) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, np.asarray(array), allow_pickle=False)
    return buffer.getvalue()


def _edit_header(entries, edit):
    header = json.loads(str(np.load(io.BytesIO(entries["__metadata__.npy"]))))
    edit(header)
    return {**entries, "__metadata__.npy": _npy(np.array(json.dumps(header)))}


def _set(key, value):
    return lambda h: h["fields"].__setitem__(key, value)


FORGED = [
    ("unknown kind", lambda e, m: _edit_header(e, lambda h: h.__setitem__(
        "format", "powerline_control.Oscillator")), "'format'"),
    ("kind not a string", lambda e, m: _edit_header(e, lambda h: h.__setitem__("format", 3)),
     "'format'"),
    ("relabelled DMDModel", lambda e, m: _edit_header(e, lambda h: h.__setitem__(
        "format", "powerline_control.DMDModel")), "'line_frequencies'"),
    ("n_lines missing", lambda e, m: _edit_header(e, lambda h: h["fields"].pop("n_lines")),
     "'n_lines'"),
    ("n_lines too many", lambda e, m: _edit_header(e, _set("n_lines", 9)), "'n_lines'"),
    ("n_lines not an int", lambda e, m: _edit_header(e, _set("n_lines", "3")), "'n_lines'"),
    ("radius above 1", lambda e, m: _edit_header(e, _set("radius", 1.01)), "'radius'"),
    ("delays forged", lambda e, m: _edit_header(e, _set("delays", 3)), "'delays'"),
    ("alpha forged", lambda e, m: _edit_header(e, _set("alpha", 0.1)), "'alpha'"),
    ("process noise edited", lambda e, m: _edit_header(e, _set("process_noise", 1.0)),
     "'process_noise'"),
    ("frequency edited", lambda e, m: {**e, "line_frequencies.npy": _npy(
        np.asarray(m.line_frequencies) + [0.0, 0.5, 0.0])}, "'line_frequencies'"),
    ("frequency above Nyquist", lambda e, m: {**e, "line_frequencies.npy": _npy(
        np.asarray(m.line_frequencies) * 100)}, "'frequencies'"),
    ("line shapes missing", lambda e, m: {k: v for k, v in e.items()
                                          if k != "line_shapes.npy"}, "['line_shapes']"),
    ("unseen wrong shape", lambda e, m: {**e, "unseen.npy": _npy(np.ones((9, 3)))}, "'unseen'"),
    ("initial state not at rest", lambda e, m: {**e, "initial_state.npy": _npy(
        np.ones(m.n_states))}, "'initial_state'"),
]


@pytest.mark.parametrize("build, fragment", [r[1:] for r in FORGED], ids=[r[0] for r in FORGED])
def test_forged_or_corrupted_oscillator_file_is_refused_naming_the_field(built, tmp_path, build,
                                                                         fragment):
    path = tmp_path / "forged.npz"
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in build(_entries(built, tmp_path), built).items():
            archive.writestr(name, data)
    with pytest.raises(FileFormatError) as info:
        plc.load_model(path)
    assert fragment in str(info.value) and str(path) in str(info.value)


def test_a_dmd_model_relabelled_as_oscillator_is_refused(tmp_path):
    dmd = plc.fit_dmd(np.random.default_rng(0).standard_normal((3, 60)), 0.01, alpha=0.1)
    entries = _entries(dmd, tmp_path)
    forged = _edit_header(entries, lambda h: h.__setitem__(
        "format", "powerline_control.OscillatorModel"))
    path = tmp_path / "forged.npz"
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in forged.items():
            archive.writestr(name, data)
    with pytest.raises(FileFormatError, match="'n_lines'"):
        plc.load_model(path)


# --------------------------------------------------------------------------- through the recipe


@pytest.fixture(scope="module")
def narrowband():
    line = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    force = plc.HarmonicForce(1.0, 18.3, 1.6)
    train = plc.simulate(line, force, duration=4.0, dt=1e-3, noise_fraction=0.01, seed=3)
    test = plc.simulate(line, force, duration=1.0, dt=1e-3, noise_fraction=0.01, seed=4)
    return train, test


def _design(train):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.ExcitationWarning)   # narrowband: it says so
        return plc.design_estimator(train, n_sensors=3, method="modal", seed=0)


def test_modal_design_returns_an_oscillator_model_that_round_trips(narrowband, tmp_path):
    train, _ = narrowband
    design = _design(train)
    model = design.model
    assert type(model) is OscillatorModel
    np.testing.assert_array_equal(model.line_frequencies, design.excitation.frequencies)
    assert np.min(np.abs(model.line_frequencies - 18.3)) < 0.01   # the load's own line
    assert f"({model.n_lines} lines, {2 * model.n_lines} states)" in design.summary()
    assert model.describe() in design.summary()
    plc.save_model(tmp_path / "design.npz", model)
    _assert_same(plc.load_model(tmp_path / "design.npz"), model)


def test_the_filter_estimates_exactly_as_with_the_dmd_typed_model(narrowband, monkeypatch):
    """The whole recipe again with the model typed as before: same sensors, same estimates."""
    import powerline_control.recipe.modal as modal

    train, test = narrowband
    design = _design(train)
    built_as = modal._modal_model
    monkeypatch.setattr(modal, "_modal_model", lambda *a, **k: _as_dmd(built_as(*a, **k)))
    before = _design(train)
    assert type(before.model) is DMDModel
    np.testing.assert_array_equal(before.sensors, design.sensors)
    np.testing.assert_array_equal(before.model.A, design.model.A)
    y = test.displacement[design.sensors]
    ours, theirs = design.filter.filter(y), before.filter.filter(y)
    np.testing.assert_allclose(ours.states, theirs.states, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours.variances, theirs.variances, rtol=0, atol=1e-12)
    np.testing.assert_allclose(design.estimate_field(y), before.estimate_field(y), rtol=0,
                               atol=1e-12)


def test_scenario_text_and_json_read_the_model_type(narrowband):
    from powerline_control.scenario.summary import _recipe_text
    from powerline_control.scenario.summary_json import _model_kind

    train, _ = narrowband
    design = _design(train)
    text = _recipe_text(design)
    assert text.startswith(design.model.describe()) and "alpha" not in text
    kind = _model_kind(design.model)
    assert kind["model_kind"] == "oscillator"
    np.testing.assert_array_equal(kind["line_frequencies_hz"], design.model.line_frequencies)
    dmd = plc.fit_dmd(np.random.default_rng(0).standard_normal((3, 60)), 0.01, alpha=0.1)
    assert _model_kind(dmd) == {"model_kind": "dmd"}
    assert "Tikhonov alpha" in _recipe_text(dataclasses.replace(design, model=dmd))
