"""Parameter studies: grid order, seeds, executors (serial, process pool, Dask), output, errors."""

import csv
import json
import math
import random
from concurrent.futures import Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.studies import StudyResult, parameter_grid, point_seed, run_study

PAPER_CONDUCTOR = plc.Span.paper_lab().conductor


def first_frequency(n_elements, tension):
    """Module-level (picklable) study function: FE against the closed form."""
    span = plc.Span(length=3.66, tension=tension, conductor=PAPER_CONDUCTOR)
    fe = plc.LineModel(span, n_elements).natural_frequencies(1)[0]
    return {"fe": fe, "exact": span.pinned_frequencies(1)[0]}


def noisy_record(n_elements, noise_std, seed):
    """A seeded study point: simulate a short noisy record and measure its sensor noise.

    The drawn noise depends on ``seed``: the result changes with the seed and must not change
    with the executor.
    """
    model = plc.LineModel(plc.Span.paper_lab(), n_elements)
    force = plc.HarmonicForce(amplitude=1.0, frequency=17.0, position=1.1)
    snap = plc.simulate(model, force, duration=0.3, dt=1e-3, noise_std=noise_std, seed=seed)
    noise = snap.displacement - snap.true_displacement
    return {"noise_std_measured": float(noise.std()), "n_samples": noise.size,
            "first_sample": float(noise[1, 0])}


def test_grid_is_the_cartesian_product_in_order():
    grid = parameter_grid(a=[1, 2], b=["x", "y", "z"])
    assert len(grid) == 6
    assert grid[0] == {"a": 1, "b": "x"} and grid[-1] == {"a": 2, "b": "z"}
    assert grid == [{"a": a, "b": b} for a in (1, 2) for b in "xyz"]  # brute-force product


def test_process_pool_gives_the_serial_results_in_grid_order(tmp_path):
    grid = parameter_grid(n_elements=[4, 8, 16], tension=[200.0, 395.0])
    serial = run_study(first_frequency, grid)
    with ProcessPoolExecutor(max_workers=2) as pool:
        parallel = run_study(first_frequency, grid, pool)
    assert parallel == serial
    # The study itself checks something real: FE converges to the closed form as h^4.
    errors = np.abs(serial.column("fe") - serial.column("exact")) / serial.column("exact")
    assert np.all(errors[4:] < errors[:2].min())
    path = serial.to_csv(tmp_path / "study.csv")
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 6 and float(rows[0]["n_elements"]) == 4


def test_seeded_study_is_identical_on_serial_process_pool_and_dask():
    """One seeded study, three executors, the same table."""
    distributed = pytest.importorskip("distributed")
    grid = parameter_grid(n_elements=[6, 9], noise_std=[2e-5, 7e-5, 1.3e-4])
    serial = run_study(noisy_record, grid, seed=2026)
    with ProcessPoolExecutor(max_workers=2) as pool:
        pooled = run_study(noisy_record, grid, pool, seed=2026)
    # Threads in one process keep the test quick and leak nothing; the executor is Dask's own
    # (scheduler, worker, futures), which is what run_study sees from any Dask cluster.
    # examples/dask_study.py (run by tests/test_examples.py) checks worker processes too.
    with (
        distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                 dashboard_address=None) as cluster,
        distributed.Client(cluster) as client,
    ):
        on_dask = run_study(noisy_record, grid, client.get_executor(), seed=2026)
        with_client = run_study(noisy_record, grid, client, seed=2026)  # the Client itself
    assert with_client == on_dask
    assert serial == pooled == on_dask
    assert serial.table() == pooled.table() == on_dask.table()
    # Seeds are the derivation documented in point_seed, recomputed here point by point.
    assert serial.seeds == tuple(point_seed(2026, point) for point in grid)
    assert len(set(serial.seeds)) == len(grid)
    # The draws do depend on the seed: another base seed gives other noise.
    other = run_study(noisy_record, grid, seed=2027)
    assert not np.any(other.column("first_sample") == serial.column("first_sample"))
    # And the study measures what it says: the sample std of N Gaussian draws has relative
    # standard error 1/sqrt(2N); 6 standard errors never fail by chance (p < 1e-8).
    measured, true = serial.column("noise_std_measured"), serial.column("noise_std")
    tolerance = 6.0 / np.sqrt(2.0 * serial.column("n_samples"))
    assert np.all(np.abs(measured / true - 1.0) < tolerance)


def test_seeds_depend_on_the_point_not_on_its_place_or_the_completion_order():
    grid = parameter_grid(n_elements=[5, 7], noise_std=[1e-5, 4e-5])
    reference = run_study(noisy_record, grid, seed=11)
    shuffled = list(grid)
    random.Random(3).shuffle(shuffled)
    assert shuffled != grid
    with ReverseCompletionExecutor(len(shuffled)) as executor:
        reordered = run_study(noisy_record, shuffled, executor, seed=11)
    by_point = {tuple(sorted(p.items())): r for p, r in zip(reference.parameters,
                                                            reference.results, strict=True)}
    for point, result in zip(reordered.parameters, reordered.results, strict=True):
        assert result == by_point[tuple(sorted(point.items()))]
    assert reordered.parameters == tuple(shuffled)  # results come back in the given order


class ReverseCompletionExecutor(Executor):
    """Runs nothing until every point is submitted, then finishes them last-first."""

    def __init__(self, n):
        self.n, self.pending = n, []

    def submit(self, fn, /, *args, **kwargs):
        future = Future()
        self.pending.append((future, fn, args, kwargs))
        if len(self.pending) == self.n:
            for waiting, func, a, kw in reversed(self.pending):
                waiting.set_result(func(*a, **kw))
        return future


def blas_threads_now(k):
    """How many threads the BLAS library would use right now (threadpoolctl's view)."""
    from threadpoolctl import threadpool_info

    counts = [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]
    return {"threads": max(counts) if counts else -1}


def test_points_run_with_one_blas_thread_and_the_limit_is_lifted_after():
    from threadpoolctl import threadpool_info

    if not any(pool["user_api"] == "blas" for pool in threadpool_info()):
        pytest.skip("no BLAS library visible to threadpoolctl")
    before = blas_threads_now(0)["threads"]  # the machine's default (2 here, 1 on one core)
    serial = run_study(blas_threads_now, parameter_grid(k=[1, 2]))
    with ThreadPoolExecutor(2) as pool:
        threaded = run_study(blas_threads_now, parameter_grid(k=range(6)), pool)
    with ProcessPoolExecutor(2) as pool:
        pool.submit(abs, -1).result()  # workers exist (forked before the study), as in reuse
        pooled = run_study(blas_threads_now, parameter_grid(k=range(4)), pool)
    assert set(pooled.column("threads")) == {1}
    untouched = run_study(blas_threads_now, parameter_grid(k=[1]), blas_threads=None)
    after = blas_threads_now(0)["threads"]
    assert set(serial.column("threads")) == {1} and set(threaded.column("threads")) == {1}
    assert untouched.column("threads")[0] == before == after  # None leaves BLAS alone


def test_table_csv_json_and_dataframe_agree(tmp_path):
    grid = parameter_grid(k=[1, 2, 3], label=["a", "b"])
    study = run_study(lambda k, label, seed: {"value": k + seed % 7, "nan": float("nan")},
                      grid, seed=4)
    table = study.table()
    assert len(table) == 6
    assert list(table[0]) == ["k", "label", "seed", "value", "nan"] == study.columns
    assert table[3]["value"] == 2 + point_seed(4, {"k": 2, "label": "b"}) % 7  # by hand
    with study.to_csv(tmp_path / "s.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [int(r["seed"]) for r in rows] == list(study.seeds)
    assert [r["label"] for r in rows] == ["a", "b"] * 3
    path = study.to_json(tmp_path / "s.json")
    document = json.loads(path.read_text())  # standard JSON (no NaN token): a tagged object
    assert document["results"][0]["nan"] == {"$float": "nan"}
    assert document["columns"] == study.columns and document["version"] == 2
    back = StudyResult.from_json(path)
    assert back.parameters == study.parameters and back.seeds == study.seeds
    assert [r["value"] for r in back.results] == list(study.column("value"))
    assert all(math.isnan(r["nan"]) for r in back.results)   # NaN came back as NaN, not None


def test_dataframe_holds_the_table():
    pytest.importorskip("pandas")  # optional: to_dataframe is the one method that needs it
    study = run_study(lambda k, seed: {"value": 2 * k}, parameter_grid(k=[1, 2, 3]), seed=9)
    frame = study.to_dataframe()
    assert list(frame.columns) == ["k", "seed", "value"] == study.columns
    assert frame["value"].tolist() == [2, 4, 6]
    assert frame["seed"].tolist() == [point_seed(9, {"k": k}) for k in (1, 2, 3)]


def test_numpy_scalars_become_plain_python_values():
    study = run_study(lambda k: {"a": np.float64(k) / 3, "b": np.int32(k), "c": np.bool_(k > 1)},
                      parameter_grid(k=[1, 2]))
    row = study.table()[1]
    assert type(row["a"]) is float and type(row["b"]) is int and type(row["c"]) is bool
    assert row == {"k": 2, "a": 2 / 3, "b": 2, "c": True}


def test_progress_bar_counts_the_points(capsys):
    with ThreadPoolExecutor(2) as pool:
        run_study(lambda k: {"k2": k * k}, parameter_grid(k=range(5)), pool, progress=True,
                  description="squares")
    err = capsys.readouterr().err
    assert "squares" in err and "5/5" in err
    run_study(lambda k: {"k2": k}, parameter_grid(k=range(3)), progress=False)
    assert capsys.readouterr().err == ""


def test_a_failing_point_is_named_in_the_error():
    def fails_at_two(k):
        if k == 2:
            raise ZeroDivisionError("boom")
        return {"value": k}   # not {"k": ...}: a result named like a parameter is refused

    for executor in (None, ThreadPoolExecutor(2)):
        with pytest.raises(ZeroDivisionError, match="boom") as info:
            run_study(fails_at_two, parameter_grid(k=[1, 2, 3]), executor)
        assert any("grid point 1, {'k': 2}" in note for note in info.value.__notes__)
        if executor is not None:
            executor.shutdown()


def ok(k):
    return {"v": k}


@pytest.mark.parametrize(
    ("func", "grid", "kwargs", "match"),
    [
        (ok, [], {}, "'grid' parameter is empty"),
        ("ok", [{"k": 1}], {}, "'func' parameter must be callable"),
        (ok, [{"k": 1}], {"executor": "pool"}, "'executor' parameter must be a concurrent"),
        (ok, [{"k": 1}], {"seed": -1}, "'seed' parameter must be >= 0"),
        (ok, [{"k": 1}], {"seed": 1.5}, "'seed' parameter must be an integer"),
        (ok, [{"k": 1}], {"progress": "yes"}, "'progress' parameter must be True"),
        (ok, [{"k": 1}], {"blas_threads": 0}, "'blas_threads' parameter must be >= 1"),
        (ok, {"k": 1}, {}, "'grid' parameter must be a sequence of dicts"),
        (ok, [3], {}, "point 0 is a int"),
        (ok, [{1: 2}], {}, "keys must be parameter names"),
        (ok, [{"": 2}], {}, "keys must be parameter names"),
        (ok, [{"k": 1, "seed": 3}], {"seed": 1}, "has a 'seed' key"),
        (ok, [{"k": np.zeros(3)}], {}, "grid value 'k' must be a scalar"),
        (lambda k: k, [{"k": 1}], {}, "must return a dict"),
        (lambda k: {"v": np.ones(2)}, [{"k": 1}], {}, "result 'v' must be a scalar"),
    ],
)
def test_bad_studies_are_refused(func, grid, kwargs, match):
    with pytest.raises(plc.InputError, match=match):
        run_study(func, grid, **kwargs)


def test_bad_grids_columns_and_files_are_refused(tmp_path):
    with pytest.raises(plc.InputError, match="'k' has no values"):
        parameter_grid(k=[])
    with pytest.raises(plc.InputError, match="'name' parameter must be a column.*Got 'w'"):
        run_study(ok, parameter_grid(k=[1])).column("w")
    with pytest.raises(plc.InputError, match="'seed' parameter must be >= 0"):
        point_seed(-3, {"k": 1})
    with pytest.raises(plc.InputError, match="'point' parameter must be a dict"):
        point_seed(1, [("k", 1)])
    # An axis is a collection of values: a bare number, a string (its characters) or a dict
    # (its keys) is refused, not iterated.
    for axis in (3, 2.5, "xy", b"xy", {"x": 1}, None):
        with pytest.raises(plc.InputError, match="grid axis 'k' must be a list"):
            parameter_grid(k=axis)
    assert parameter_grid(k=range(2), s=("xy",)) == [{"k": 0, "s": "xy"}, {"k": 1, "s": "xy"}]
    assert len(parameter_grid(k=np.arange(3), j=iter([1, 2]))) == 6
    # 1e6 x 1e6 points: refused from the axis lengths, naming them, before any point is built.
    with pytest.raises(plc.InputError, match="'axes' parameter is 'a: 1000000 x b: 1000000'"):
        parameter_grid(a=range(10**6), b=range(10**6))
    for grid in (float("nan"), 3, None):
        with pytest.raises(plc.InputError, match="'grid' parameter must be a sequence of dicts"):
            run_study(ok, grid)
    (tmp_path / "other.json").write_text('{"format": "something else"}')
    with pytest.raises(plc.FileFormatError, match="not a study written by"):
        StudyResult.from_json(tmp_path / "other.json")
    (tmp_path / "broken.json").write_text("{not json")
    with pytest.raises(plc.FileFormatError, match="Cannot read the study file"):
        StudyResult.from_json(tmp_path / "broken.json")
    (tmp_path / "partial.json").write_text('{"format": "powerline_control.study"}')
    with pytest.raises(plc.FileFormatError, match="incomplete or damaged"):
        StudyResult.from_json(tmp_path / "partial.json")


FIRST_STUDY_SCRIPT = """
import sys
from powerline_control.studies import parameter_grid, run_study

def threads_after_importing_scipy(k):
    import scipy.linalg  # loads SciPy's own BLAS, possibly for the first time here
    from threadpoolctl import threadpool_info
    return {"threads": max(p["num_threads"] for p in threadpool_info()
                           if p["user_api"] == "blas")}

assert "scipy.linalg" not in sys.modules
print(run_study(threads_after_importing_scipy, parameter_grid(k=[1, 2])).column("threads"))
"""


def test_the_first_point_of_a_fresh_process_is_limited_too():
    """A library loaded by the first point must not escape the limit (threadpoolctl limits only
    the libraries loaded when the limit is set)."""
    import os
    import subprocess
    import sys

    root = str(__import__("pathlib").Path(__file__).resolve().parents[1])
    result = subprocess.run([sys.executable, "-c", FIRST_STUDY_SCRIPT], capture_output=True,
                            text=True, env={**os.environ, "PYTHONPATH": root}, timeout=300,
                            check=False)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[1 1]"


def test_a_script_study_function_pickles_with_the_package_in_its_globals():
    """Dask (cloudpickle) sends a script's function by value, with ``plc`` among its globals;
    the package must then pickle by name, as modules do (a plain module object: the standard
    library's pickle refuses every module, cloudpickle sends one by name)."""
    import types

    cloudpickle = pytest.importorskip("cloudpickle")
    assert type(plc) is types.ModuleType
    assert cloudpickle.loads(cloudpickle.dumps(plc)) is plc

    def in_a_script(k):
        return {"f1": float(plc.Span.paper_lab().pinned_frequencies(1)[0] * k)}

    in_a_script.__module__ = "__main__"  # what a function defined in a script looks like
    again = cloudpickle.loads(cloudpickle.dumps(in_a_script))
    assert again(2) == in_a_script(2)


def test_dotted_keys_reach_a_function_that_takes_keyword_arguments():
    """The CLI's study verb varies TOML keys such as "estimation.n_sensors"."""
    def point(**keys):
        return {"n": keys["estimation.n_sensors"] * 10}

    study = run_study(point, parameter_grid(**{"estimation.n_sensors": [2, 3]}), seed=1)
    assert list(study.column("n")) == [20, 30]
    assert study.columns == ["estimation.n_sensors", "seed", "n"]


# ------------------------------------------------------------------ results lose nothing
def _same_row(a: dict, b: dict) -> bool:
    """Equal keys, and values bit-for-bit (NaN equal to NaN, types kept: 1 is not 1.0)."""
    return list(a) == list(b) and all(
        type(a[k]) is type(b[k]) and (repr(a[k]) == repr(b[k])) for k in a)


def test_json_round_trip_keeps_nan_and_infinities_bit_for_bit(tmp_path):
    # Old code wrote NaN and +-inf as null and read them back as None.
    values = {"nan": math.nan, "inf": math.inf, "minus_inf": -math.inf, "tiny": 5e-324,
              "big": 1.7976931348623157e308, "third": 1 / 3, "int": 3, "text": "NaN",
              "none": None, "flag": True}
    study = run_study(lambda a: dict(values), parameter_grid(a=[math.nan, math.inf, 1.0]))
    back = StudyResult.from_json(study.to_json(tmp_path / "s.json"))
    assert all(_same_row(r, s) for r, s in zip(back.results, study.results, strict=True))
    assert all(_same_row(r, s) for r, s in zip(back.parameters, study.parameters, strict=True))
    assert back.results[0]["text"] == "NaN"     # a string "NaN" stays a string


def test_json_version_1_files_still_read(tmp_path):
    old = {"format": "powerline_control.study", "version": 1, "base_seed": None,
           "columns": ["a", "b"], "parameters": [{"a": 1}], "seeds": None,
           "results": [{"b": None}]}
    (tmp_path / "v1.json").write_text(json.dumps(old))
    assert StudyResult.from_json(tmp_path / "v1.json").results == ({"b": None},)
    old["version"] = 3
    (tmp_path / "v3.json").write_text(json.dumps(old))
    with pytest.raises(plc.FileFormatError, match="version 3"):
        StudyResult.from_json(tmp_path / "v3.json")


def test_result_named_like_a_parameter_is_refused():
    # Old code: table() let the result overwrite the parameter's column.
    with pytest.raises(plc.InputError, match=r"\['k'\].*named like the study's parameters"):
        run_study(lambda k: {"k": 2 * k}, parameter_grid(k=[1, 2]))
    with pytest.raises(plc.InputError, match="'seed'"):
        run_study(lambda k, seed: {"seed": seed}, parameter_grid(k=[1]), seed=3)
    with pytest.raises(plc.InputError, match="named like"):
        StudyResult(parameters=({"k": 1},), results=({"k": 2},))


def test_points_with_different_keys_are_refused_before_any_runs():
    calls = []

    def count(**point):
        calls.append(point)
        return {"n": len(point)}

    # Old code ran both points and failed later in to_csv.
    with pytest.raises(plc.InputError, match="point 1 has the keys \\['b'\\] but point 0"):
        run_study(count, [{"a": 1}, {"b": 2}])
    assert calls == []


def test_results_with_different_keys_are_refused_when_they_arrive():
    with pytest.raises(plc.InputError, match="returned the keys \\['y'\\] at grid point 1"):
        run_study(lambda a: {"x": 1} if a == 1 else {"y": 1}, parameter_grid(a=[1, 2]))


@pytest.mark.parametrize("where", ["folder", "missing", "empty"])
def test_study_files_refuse_a_folder_a_missing_folder_and_empty(tmp_path, where):
    study = run_study(lambda a: {"b": a}, parameter_grid(a=[1]))
    target = {"folder": tmp_path, "missing": tmp_path / "no" / "s.json", "empty": ""}[where]
    # Old code: IsADirectoryError, FileNotFoundError, or '' read as the working folder.
    for call in (study.to_json, study.to_csv, StudyResult.from_json):
        with pytest.raises(plc.InputError, match="'path'"):
            call(target)


FIFO_SCRIPT = """
import os, sys
import powerline_control as plc
fifo = os.path.join(sys.argv[1] if len(sys.argv) > 1 else {folder!r}, "fifo")
os.mkfifo(fifo)
study = plc.run_study(lambda a: {{"b": a}}, plc.parameter_grid(a=[1]))
for call in (study.to_json, study.to_csv, plc.StudyResult.from_json):
    try:
        call(fifo)
    except plc.InputError as error:
        print("refused", "'path'" in str(error))
"""


def test_study_files_refuse_a_fifo_without_blocking(tmp_path):
    import sweep_cases

    # Old code blocked forever opening the FIFO (no reader): in a subprocess with a timeout.
    out = sweep_cases.guarded(FIFO_SCRIPT.format(folder=str(tmp_path)), timeout=60.0)
    assert out.split() == ["refused", "True"] * 3, out
