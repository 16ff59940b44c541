"""A seeded estimation study on a local Dask cluster, checked against the same study run serially.

How well does a Kalman filter on the identified model estimate the whole of the paper's span, as
the sensor noise, the number of sensors and the forcing frequency change? Each grid point
simulates its own training and test records from its own seed (derived from the point's values
by ``run_study(..., seed=...)``), so the Dask cluster and the serial run give the same table.

Run: python examples/dask_study.py [out_dir] [--workers N] [--fast]   (default out/; 30 s on 2
cores at load average 6, 18 s with --fast; needs the dask extra: pip install
"powerline_control[dask]"; writes dask_study.csv, dask_study.json and dask_study.png)

On a real cluster, replace the LocalCluster by ``Client("tcp://scheduler-address:8786")``; the
study function only has to be importable or defined in the script (Dask pickles it).
"""

import argparse
import logging
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import powerline_control as plc  # noqa: E402


def estimation_error(noise_fraction: float, n_sensors: int, frequency: float, seed: int) -> dict:
    """Relative RMS error of the whole-span Kalman estimate at one grid point."""
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=20)
    force = plc.HarmonicForce(amplitude=1.0, frequency=frequency, position=0.5)
    train_seed, test_seed = np.random.default_rng(seed).integers(2**32, size=2)
    # The training run adds a broadband shaker: a harmonic record alone is not persistently
    # exciting (design_estimator warns), and the estimator should not depend on its luck.
    shaker = plc.RandomForce(0.5, 1.1, 100.0, seed=int(train_seed))
    train = plc.simulate(model, [force, shaker], duration=2.0, dt=1e-3,
                         noise_fraction=noise_fraction, seed=int(train_seed))
    test = plc.simulate(model, force, duration=1.0, dt=1e-3, noise_fraction=noise_fraction,
                        seed=int(test_seed), start_time=2.7)
    # Spread sensors, off the supports (nodes 0 and 20 never move); the package's recipe
    # identifies the model (delays, rank, alpha from held-out data) and builds the filter.
    sensors = np.linspace(3, 17, n_sensors).round().astype(int).tolist()
    design = plc.design_estimator(train, sensors=sensors, seed=int(train_seed))
    field = design.estimate_field(test.displacement[sensors], noise_std=test.noise_std)
    acc = plc.estimation_accuracy(field, test.true_displacement, measured=sensors, discard=200)
    return {"relative_rms_error": acc.relative_rms_error,
            "unmeasured_rms_error": acc.relative_rms_error_unmeasured}


def main(out: Path, workers: int, fast: bool) -> None:
    from dask.distributed import Client, LocalCluster  # the optional extra: imported here

    out.mkdir(parents=True, exist_ok=True)
    grid = plc.parameter_grid(
        noise_fraction=[0.005, 0.02] if fast else [0.002, 0.005, 0.01, 0.02],
        n_sensors=[2, 3, 5],
        frequency=[19.0] if fast else [19.0, 24.0],
    )
    print(f"{len(grid)} grid points on a local Dask cluster of {workers} worker processes")
    start = time.perf_counter()
    with (
        LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                     dashboard_address=None, silence_logs=logging.ERROR) as cluster,
        Client(cluster) as client,
    ):
        on_dask = plc.run_study(estimation_error, grid, client.get_executor(), seed=2026,
                                description="Dask")
    dask_time = time.perf_counter() - start
    serial = plc.run_study(estimation_error, grid, seed=2026, description="serial")
    print(f"Dask (including cluster start-up) {dask_time:.1f} s, serial {serial.wall_time:.1f} s;"
          f" identical tables: {on_dask == serial}")
    if on_dask != serial:
        raise SystemExit("the Dask and serial studies differ: this is a bug, please report it")

    print("\n| noise | sensors | f (Hz) | error, all nodes | error, unmeasured |")
    print("|---:|---:|---:|---:|---:|")
    for row in on_dask.table():
        print(f"| {row['noise_fraction']:.1%} | {row['n_sensors']} | {row['frequency']:g} | "
              f"{row['relative_rms_error']:.2%} | {row['unmeasured_rms_error']:.2%} |")
    on_dask.to_csv(out / "dask_study.csv")
    on_dask.to_json(out / "dask_study.json")

    fig, ax = plt.subplots(figsize=(6, 3.5))
    table = on_dask.table()
    for frequency in sorted({row["frequency"] for row in table}):
        for n in sorted({row["n_sensors"] for row in table}):
            rows = [r for r in table if r["n_sensors"] == n and r["frequency"] == frequency]
            ax.loglog([100 * r["noise_fraction"] for r in rows],
                      [100 * r["relative_rms_error"] for r in rows], "o-",
                      label=f"{n} sensors, {frequency:g} Hz")
    ax.set(xlabel="sensor noise (% of RMS displacement)",
           ylabel="estimation error (% of RMS)", title="Whole-span Kalman estimate, paper span")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "dask_study.png", dpi=110)
    plt.close(fig)
    print(f"\nwrote {out / 'dask_study.csv'}, {out / 'dask_study.json'}, {out / 'dask_study.png'}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out", nargs="?", default="out", type=Path,
                        help="output folder (default: ./out)")
    parser.add_argument("--workers", type=int, default=2, help="Dask worker processes")
    parser.add_argument("--fast", action="store_true", help="a smaller grid (CI)")
    arguments = parser.parse_args()
    main(arguments.out, arguments.workers, arguments.fast)
