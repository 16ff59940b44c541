"""Hostile files for io.load_model: each is refused from its headers, with a message naming it.

The files are built here byte by byte with zipfile and numpy.lib.format (independent of
save_model's writer); the memory claims are checked with tracemalloc (numpy reports its buffers).
"""

from __future__ import annotations

import io
import json
import os
import sys
import tracemalloc
import zipfile

import numpy as np
import pytest
from numpy.lib import format as npy_format

import powerline_control as plc
from powerline_control.errors import FileFormatError


def small_model(**kwargs) -> plc.DMDModel:
    rng = np.random.default_rng(31)
    return plc.fit_dmd(rng.standard_normal((3, 60)), 0.01, **{"alpha": 0.1, **kwargs})


def npy_bytes(array: np.ndarray, version=(1, 0)) -> bytes:
    buffer = io.BytesIO()
    npy_format.write_array(buffer, np.asanyarray(array), version=version, allow_pickle=True)
    return buffer.getvalue()


def entries_of(model: plc.DMDModel, tmp_path) -> dict[str, bytes]:
    """The raw .npy bytes of every entry save_model writes."""
    path = tmp_path / "good.npz"
    plc.save_model(path, model)
    with zipfile.ZipFile(path) as archive:
        return {info.filename: archive.read(info) for info in archive.infolist()}


def write_zip(path, entries: dict[str, bytes], compression=zipfile.ZIP_STORED) -> None:
    with zipfile.ZipFile(path, "w", compression=compression) as archive:
        for name, data in entries.items():
            archive.writestr(name, data)


def metadata_entry(entries: dict[str, bytes], edit) -> dict[str, bytes]:
    text = str(np.load(io.BytesIO(entries["__metadata__.npy"]), allow_pickle=False))
    header = json.loads(text)
    edit(header)
    return {**entries, "__metadata__.npy": npy_bytes(np.array(json.dumps(header)))}


def with_array(entries, name, array, version=(1, 0)):
    return {**entries, f"{name}.npy": npy_bytes(array, version)}


def huge_header(shape, descr="<f8") -> bytes:
    """A .npy header declaring ``shape`` followed by only 16 bytes of data."""
    header = {"descr": descr, "fortran_order": False, "shape": shape}
    buffer = io.BytesIO()
    npy_format.write_array_header_1_0(buffer, header)
    return buffer.getvalue() + bytes(16)


def set_field(key, value):
    def edit(header):
        header["fields"][key] = value
    return edit


def non_psd(model):
    q = np.array(model.residual_covariance)
    q[0, 0] = -abs(q).max() - 1.0
    return q


def non_symmetric(model):
    q = np.array(model.residual_covariance)
    q[0, 1] += 1.0
    return q


# Each row: (id, builder(entries, model) -> entries, message fragment that names what is wrong)
HOSTILE_ENTRIES = [
    ("A has NaN", lambda e, m: with_array(e, "A", np.full(m.A.shape, np.nan)), "'A' contains NaN"),
    ("initial_state has inf", lambda e, m: with_array(e, "initial_state",
                                                      np.full(m.n_states, np.inf)),
     "'initial_state' contains NaN"),
    ("A float16", lambda e, m: with_array(e, "A", m.A.astype(np.float16)), "float16"),
    ("A float32", lambda e, m: with_array(e, "A", m.A.astype(np.float32)), "float32"),
    ("A int64", lambda e, m: with_array(e, "A", m.A.astype(np.int64)), "int64"),
    ("A complex", lambda e, m: with_array(e, "A", m.A.astype(complex)), "complex128"),
    ("A big-endian", lambda e, m: with_array(e, "A", m.A.astype(">f8")), "'A' is declared >f8"),
    ("A object array (pickle)", lambda e, m: with_array(e, "A", np.array([{"x": 1}, None],
                                                                         dtype=object)),
     "pickle"),
    ("A not square", lambda e, m: with_array(e, "A", np.ones((3, 4))), "'A' is declared"),
    ("A header claims 1e9 x 1e9", lambda e, m: {**e, "A.npy": huge_header((10**9, 10**9))},
     "'A' is declared"),
    ("A header matches but data short", lambda e, m: {**e, "A.npy": huge_header(m.A.shape)},
     "truncated"),
    ("A npy version 3.0", lambda e, m: with_array(e, "A", m.A, version=(3, 0)),
     "no valid .npy header"),
    ("A not npy at all", lambda e, m: {**e, "A.npy": b"hello world" * 10},
     "no valid .npy header"),
    ("residual_covariance not PSD", lambda e, m: with_array(e, "residual_covariance",
                                                            non_psd(m)),
     "not positive semidefinite"),
    ("residual_covariance not symmetric", lambda e, m: with_array(e, "residual_covariance",
                                                                  non_symmetric(m)),
     "not symmetric"),
    ("has_B false but B present", lambda e, m: with_array(e, "B", np.ones((m.n_states, 1))),
     "has_B=False"),
    ("has_B true but B missing", lambda e, m: metadata_entry(e, set_field("has_B", True)),
     "lacks the array(s) ['B']"),
    ("has_B not a bool", lambda e, m: metadata_entry(e, set_field("has_B", "yes")), "'has_B'"),
    ("rank without basis", lambda e, m: metadata_entry(e, set_field("rank", 3)), "has_basis"),
    ("n_nodes huge", lambda e, m: metadata_entry(e, set_field("n_nodes", 10**7)),
     "over the limit"),
    ("delays not an int", lambda e, m: metadata_entry(e, set_field("delays", 1.5)), "'delays'"),
    ("dt NaN", lambda e, m: metadata_entry(e, set_field("dt", float("nan"))), "'dt'"),
    ("dt zero", lambda e, m: metadata_entry(e, set_field("dt", 0.0)), "'dt' must be > 0"),
    ("alpha negative", lambda e, m: metadata_entry(e, set_field("alpha", -1.0)), "'alpha'"),
    ("metadata lacks n_pairs", lambda e, m: metadata_entry(e, lambda h: h["fields"].pop(
        "n_pairs")), "'n_pairs'"),
    ("metadata is a float array", lambda e, m: with_array(e, "__metadata__", np.ones(3)),
     "one text string"),
    ("metadata not JSON", lambda e, m: with_array(e, "__metadata__", np.array("{nope")),
     "metadata"),
    ("foreign format", lambda e, m: metadata_entry(e, lambda h: h.__setitem__(
        "format", "sklearn.Pipeline")), "sklearn.Pipeline"),
    ("future version", lambda e, m: metadata_entry(e, lambda h: h.__setitem__("version", 7)),
     "version 7"),
    ("unexpected entry", lambda e, m: {**e, "payload.py": b"print('hi')"}, "'payload.py'"),
    ("metadata missing", lambda e, m: {k: v for k, v in e.items() if k != "__metadata__.npy"},
     "'__metadata__'"),
    ("A missing", lambda e, m: {k: v for k, v in e.items() if k != "A.npy"}, "['A']"),
]


@pytest.mark.parametrize("build, fragment", [r[1:] for r in HOSTILE_ENTRIES],
                         ids=[r[0] for r in HOSTILE_ENTRIES])
def test_hostile_archive_is_refused_with_a_clear_message(tmp_path, build, fragment):
    model = small_model()
    path = tmp_path / "hostile.npz"
    write_zip(path, build(entries_of(model, tmp_path), model))
    with pytest.raises(FileFormatError) as info:
        plc.load_model(path)
    assert fragment in str(info.value)
    assert str(path) in str(info.value)  # and which file


def rank_model_entries(tmp_path):
    model = small_model(rank=2, delays=2, alpha=0.0)
    return model, entries_of(model, tmp_path)


@pytest.mark.parametrize(
    "change, fragment",
    [
        (lambda m: np.array(m.basis) * 2.0, "orthonormal"),
        (lambda m: np.roll(np.array(m.basis), 1, axis=0), "leading rows"),
    ],
    ids=["basis scaled", "field_map not basis rows"],
)
def test_inconsistent_basis_is_refused(tmp_path, change, fragment):
    model, entries = rank_model_entries(tmp_path)
    path = tmp_path / "basis.npz"
    write_zip(path, with_array(entries, "basis", change(model)))
    with pytest.raises(FileFormatError, match=fragment):
        plc.load_model(path)


def test_zip_bomb_is_refused_from_its_directory_without_memory(tmp_path):
    """490 MB of zeros deflate to about 0.5 MB: refused before any byte is inflated."""
    model = small_model()
    entries = entries_of(model, tmp_path)
    path = tmp_path / "bomb.npz"
    write_zip(path, entries)
    chunk = bytes(2**20)
    with zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open("basis.npy", "w", force_zip64=True) as stream:
            for _ in range(490):
                stream.write(chunk)
    assert os.path.getsize(path) < 2 * 2**20  # the bomb is small on disk
    tracemalloc.start()
    try:
        with pytest.raises(FileFormatError, match="zip bomb"):
            plc.load_model(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20  # far below the 490 MB it would unpack to


@pytest.mark.parametrize("path", [3, 2.5, None, ["model.npz"], ""])
def test_save_model_refuses_a_path_that_is_not_one(path):
    # np.savez raised a raw TypeError (or wrote '.npz' for an empty name).
    with pytest.raises(plc.InputError, match="'path' parameter"):
        plc.save_model(path, small_model())


def test_save_model_still_writes_to_an_open_binary_file(tmp_path):
    model = small_model()
    with open(tmp_path / "open.npz", "wb") as handle:
        plc.save_model(handle, model)
    assert np.array_equal(plc.load_model(tmp_path / "open.npz").A, model.A)  # exact copy


def test_declared_sizes_over_max_bytes_are_refused(tmp_path):
    path = tmp_path / "model.npz"
    plc.save_model(path, small_model())
    with pytest.raises(FileFormatError, match="max_bytes"):
        plc.load_model(path, max_bytes=100)


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_dev_zero_is_not_read():
    with pytest.raises(FileFormatError, match="not a regular file"):
        plc.load_model("/dev/zero")


@pytest.mark.skipif(sys.platform == "win32", reason="needs os.mkfifo")
def test_fifo_is_not_opened(tmp_path):
    fifo = tmp_path / "pipe.npz"
    os.mkfifo(fifo)
    # Opening a FIFO for reading blocks until a writer appears: the check must come first.
    with pytest.raises(FileFormatError, match="not a regular file"):
        plc.load_model(fifo)


def test_directory_is_refused(tmp_path):
    with pytest.raises(FileFormatError, match="not a regular file"):
        plc.load_model(tmp_path)


def test_empty_file_is_refused(tmp_path):
    path = tmp_path / "empty.npz"
    path.write_bytes(b"")
    with pytest.raises(FileFormatError, match="not a zip archive"):
        plc.load_model(path)


def test_fortran_ordered_and_deflated_entries_load_exactly(tmp_path):
    """Legitimate variations (another writer's array order, a re-zipped file) load bit for bit."""
    model = small_model(delays=2)
    entries = entries_of(model, tmp_path)
    entries = with_array(entries, "A", np.asfortranarray(model.A))
    path = tmp_path / "variant.npz"
    write_zip(path, entries, compression=zipfile.ZIP_DEFLATED)
    loaded = plc.load_model(path)
    assert loaded.A.tobytes() == model.A.tobytes()
    assert loaded.residual_covariance.tobytes() == model.residual_covariance.tobytes()


@pytest.mark.parametrize("kwargs", [{"alpha": 0.1}, {"rank": 2, "delays": 2, "alpha": 1e-3},
                                    {"inputs": "u", "alpha": 0.01, "delays": 2}])
def test_round_trip_keeps_every_field_including_the_gram(tmp_path, kwargs):
    rng = np.random.default_rng(5)
    X = rng.standard_normal((3, 80))
    if kwargs.get("inputs") == "u":
        kwargs = {**kwargs, "inputs": rng.standard_normal((1, 80))}
    model = plc.fit_dmd(X, 0.01, **kwargs)
    path = tmp_path / "m.npz"
    plc.save_model(path, model)
    loaded = plc.load_model(path)
    for name in ("A", "B", "field_map", "basis", "residual_covariance", "initial_state",
                 "regressor_gram"):
        a, b = getattr(model, name), getattr(loaded, name)
        assert (a is None and b is None) or a.tobytes() == b.tobytes(), name


# ------------------------------------------------------------------ bad paths, limits
def test_save_model_onto_a_folder_is_refused_not_written_beside_it(tmp_path):
    model = small_model()
    folder = tmp_path / "models"
    folder.mkdir()
    # Old code: np.savez wrote models.npz next to the folder and returned as if done.
    with pytest.raises(plc.InputError, match="'path' parameter .* is a folder"):
        plc.save_model(folder, model)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["models"]
    with pytest.raises(plc.InputError, match="does not exist"):
        plc.save_model(tmp_path / "no" / "m.npz", model)
    os.mkfifo(tmp_path / "pipe.npz")   # np.savez onto a FIFO blocks until a reader comes
    import sweep_cases

    out = sweep_cases.guarded(
        "import numpy as np, powerline_control as plc\n"
        "m = plc.fit_dmd(np.random.default_rng(31).standard_normal((3, 60)), 0.01, alpha=0.1)\n"
        f"try:\n    plc.save_model({str(tmp_path / 'pipe.npz')!r}, m)\n"
        "except plc.InputError as e:\n    print('refused', 'not a regular file' in str(e))\n",
        timeout=60.0)
    assert out.split() == ["refused", "True"], out


@pytest.mark.parametrize("bad", [float("nan"), "1e6", True, -1.0, 0.0, float("inf")])
def test_load_model_validates_max_bytes_before_using_it(tmp_path, bad):
    path = tmp_path / "m.npz"
    plc.save_model(path, small_model())
    # Old code: float("1e6") took the text as a number; nan made every "size > limit" false.
    with pytest.raises(plc.InputError, match="'max_bytes'"):
        plc.load_model(path, max_bytes=bad)
    assert plc.load_model(path, max_bytes=1e6).A.shape == small_model().A.shape
