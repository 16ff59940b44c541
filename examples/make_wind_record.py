"""Generate the synthetic wind record shipped as examples/data/wind_record_28d.csv.

Four weeks of 10-minute means, seed 2026 (WindRecord.synthetic documents the model):

- wind speed: Weibull marginal (k = 2, c = 4 m/s) from a Gaussian AR(1) process with a 3 h
  correlation time, times the diurnal factor 1 + 0.3 sin(2 pi (hour - 9) / 24);
- direction: prevailing 250 degrees (WSW) wandering by 40 degrees (AR(1), 3 h);
- air temperature: 10 degC + 6 degC sin(2 pi (hour - 9) / 24) + 3 degC synoptic AR(1) (2 days);
- turbulence intensity: 0.15 - 0.01 V + 0.02 white noise, clipped to 0.03-0.4.

It is an illustration of a record's shape, not a site's climate. The same seed gives the same
file (tests/test_wind_record.py regenerates it and compares).

Run: python examples/make_wind_record.py OUTPUT_FOLDER   (writes wind_record_28d.csv there; 3 s on
2 cores at load average 6)
"""

from __future__ import annotations

import pathlib
import sys

import powerline_control as plc

SEED = 2026
DAYS = 28.0
STEP = 600.0


def make_record() -> plc.WindRecord:
    """The shipped record: WindRecord.synthetic with this script's seed and length."""
    return plc.WindRecord.synthetic(days=DAYS, step=STEP, seed=SEED)


def main(output: pathlib.Path) -> pathlib.Path:
    output.mkdir(parents=True, exist_ok=True)
    record = make_record()
    path = output / "wind_record_28d.csv"
    record.to_csv(path)
    print(f"{record.n_records} records of {record.step:g} s ({record.duration / 86400:g} days): "
          f"mean wind {record.wind_speed.mean():.2f} m/s, temperature "
          f"{record.temperature.min():.1f} to {record.temperature.max():.1f} degC -> {path}")
    return path


if __name__ == "__main__":
    main(pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else pathlib.Path("."))
