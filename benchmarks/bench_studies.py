"""Benchmark: one seeded study on the serial, process-pool and Dask executors (same table).

Run: python benchmarks/bench_studies.py [--points N]

The study is the estimation study of ``examples/dask_study.py`` (a Kalman estimate of the paper's
span per grid point). Prints wall time per executor, the speed-up over serial and whether the
tables are identical (they must be: seeds come from the grid points, BLAS runs one thread per
point). Dask is timed with cluster start-up (a LocalCluster of worker processes), on the fresh
cluster (its workers import the package on their first task) and again on the warm cluster.
BLAS is pinned to one thread (benchmarks/_common.py).
"""

from _common import PINNED  # noqa: I001  (pins BLAS before numpy is imported)

import argparse
import logging
import pathlib
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import powerline_control as plc

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main(points: int, workers: int) -> None:
    from dask.distributed import Client, LocalCluster

    sys.path.insert(0, str(ROOT / "examples"))  # workers inherit sys.path and import it
    from dask_study import estimation_error as study_function
    noise = [0.002 * 1.5**i for i in range(max(1, points // 6))]
    grid = plc.parameter_grid(noise_fraction=noise, n_sensors=[2, 3, 5], frequency=[19.0, 24.0])
    print(f"{PINNED}\n{len(grid)} grid points, {workers} workers\n")
    rows = []
    start = time.perf_counter()
    serial = plc.run_study(study_function, grid, seed=1)
    rows.append(("serial", time.perf_counter() - start, True))
    start = time.perf_counter()
    with ProcessPoolExecutor(max_workers=workers) as pool:
        pooled = plc.run_study(study_function, grid, pool, seed=1)
    rows.append((f"ProcessPoolExecutor({workers})", time.perf_counter() - start, pooled == serial))
    start = time.perf_counter()
    with (LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                       dashboard_address=None, silence_logs=logging.ERROR) as cluster,
          Client(cluster) as client):
        started = time.perf_counter()
        on_dask = plc.run_study(study_function, grid, client.get_executor(), seed=1)
        done = time.perf_counter()
        again = plc.run_study(study_function, grid, client.get_executor(), seed=1)
        warm = time.perf_counter() - done
    rows.append((f"Dask LocalCluster({workers} processes), cluster start-up + first run",
                 done - start, on_dask == serial))
    rows.append(("Dask, first run (workers import the package)", done - started,
                 on_dask == serial))
    rows.append(("Dask, second run (warm workers)", warm, again == serial))
    print("| executor | wall time (s) | speed-up vs serial | identical table |")
    print("|---|---:|---:|---|")
    for name, seconds, same in rows:
        print(f"| {name} | {seconds:.2f} | {rows[0][1] / seconds:.2f}x | {same} |")


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=int, default=24, help="about this many grid points")
    parser.add_argument("--workers", type=int, default=2)
    arguments = parser.parse_args()
    main(arguments.points, arguments.workers)
