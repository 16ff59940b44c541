"""Parameter studies: grid order, executors, CSV output, errors."""

import csv
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.studies import parameter_grid, run_study


def first_frequency(n_elements, tension):
    """Module-level (picklable) study function: FE against the closed form."""
    span = plc.Span(length=3.66, tension=tension, conductor=plc.Span.paper_lab().conductor)
    fe = plc.LineModel(span, n_elements).natural_frequencies(1)[0]
    return {"fe": fe, "exact": span.pinned_frequencies(1)[0]}


def test_grid_is_the_cartesian_product_in_order():
    grid = parameter_grid(a=[1, 2], b=["x", "y", "z"])
    assert len(grid) == 6
    assert grid[0] == {"a": 1, "b": "x"} and grid[-1] == {"a": 2, "b": "z"}


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


def test_bad_studies_are_reported():
    with pytest.raises(plc.InputError, match="empty"):
        run_study(first_frequency, [])
    with pytest.raises(plc.InputError, match="must return a dict"):
        run_study(lambda k: k, parameter_grid(k=[1]))
    with pytest.raises(plc.InputError, match="no values"):
        parameter_grid(k=[])
    with pytest.raises(plc.InputError, match="No column"):
        run_study(lambda k: {"v": k}, parameter_grid(k=[1])).column("w")
