"""Munich UniBw test bridge, inclinometer INC01: its noise estimated by ``sensorplan noise``.

Data: imcs-compsim/munich-bridge-data (commit f1057c1, MIT licence,
"Copyright (c) 2022 imcs-compsim"; Jaelani et al., "Developing a benchmark
study for bridge monitoring", Steel Construction 16 (2023) 215).  They are
not part of this repository; the study looks for them in
``../shared/realdata/munich_unibw_testbridge_sample`` next to the repository
root and skips with one line when they are absent.  The figures and the
derived table it writes carry that attribution.

Two records of the raw INC01 channel at 100 Hz, in degrees with ISO
timestamps (millisecond stamps that jitter between 8 and 12 ms): the
reference state of 2022-03-07 (10 min) and the support-load test of
2022-04-11 (12 min, load steps).  Each is converted only by stating its
unit: a CSV ``time_s,INC01`` with the timestamps as they are and a case
whose ``[logger] tilt_unit = "deg"``, read by ``sensorplan.io.logger``.  The
estimator runs at the logger's rate and on every 10th sample (10 Hz: the
record has vibration at 5-10 Hz and 40-50 Hz that the white + OU + walk
model lacks; sub-sampling folds it into the white part).

Run: python studies/realdata/munich_noise.py [--data DIR] [--out DIR] [--table CSV]
Findings: docs/noise.md, section "The real record".
"""

import argparse
import csv
import io
import sys
import tempfile
import time as clock
import zipfile
from pathlib import Path

from sensorplan.acquisition.noise import estimate_noise
from sensorplan.io.config import case_from_toml
from sensorplan.io.logger import read_timeseries
from sensorplan.model.timeseries import LoggerFormat

REPO = Path(__file__).resolve().parents[2]
DATA_DIR = REPO.parent / "shared" / "realdata" / "munich_unibw_testbridge_sample"
TABLE = REPO / "studies" / "realdata" / "derived" / "munich_inc01_noise.csv"
RECORDS = {"reference 2022-03-07": ("ReferenceStateINCAt100Hz.csv.zip", "INC-01 [deg]"),
           "support load 2022-04-11": ("UniBw_2022-04-11_ref_support_load_01AllM100Hz.csv.zip", "INC01 [deg]")}
ATTRIBUTION = ("Data: imcs-compsim/munich-bridge-data (MIT licence, (c) 2022 imcs-compsim); Jaelani et al., "
               "Steel Construction 16 (2023) 215. Noise estimated by sensorplan.")
CASE = """
[bridge]
spans = [20.0]
ei = 1.0e10
[vehicle]
axle_offsets = [0.0]
axle_loads = [1.0e5]
[sensors]
names = ["INC01"]
positions = [5.0]
kinds = ["rotation"]
noise_std = 2.0e-5
"""


def _csv_text(path):
    """The CSV inside the zip (its one member; named .csv.zip upstream but plain text)."""
    with zipfile.ZipFile(path) as archive:
        return archive.read(archive.namelist()[0]).decode("utf-8")


def read_record(path, column, folder):
    """The INC01 channel as a TimeSeries, through the package's reader: degrees, ISO timestamps."""
    rows = csv.reader(io.StringIO(_csv_text(path)))
    header = next(rows)
    j = header.index(column)
    log = Path(folder) / (Path(path).stem + ".csv")
    with open(log, "w") as fh:
        fh.write("time_s,INC01\n")
        for row in rows:
            fh.write(f"{row[0]},{row[j]}\n")
    case = case_from_toml(CASE)
    return read_timeseries(log, case.sensors, LoggerFormat(tilt_unit="deg"))


def run(data_dir, out, table):
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for label, (name, column) in RECORDS.items():
            series = read_record(data_dir / name, column, folder)
            for rate in (None, 10.0):
                start = clock.process_time()
                result = estimate_noise(series, max_rate=rate)
                cpu = clock.process_time() - start
                c = result.channels[0]
                tag = f"{label}, {'100 Hz' if rate is None else '10 Hz'}"
                print(f"== {tag} (fit {cpu:.1f} s CPU)")
                print(result.summary())
                rows.append(_row(tag, result, c))
                if out is not None:
                    _figure(result, out / f"munich_inc01_{label.split()[0]}_{'100' if rate is None else '10'}hz.png")
    _write_table(table, rows)
    print(f"table: {table}")


def _row(tag, result, c):
    def pair(est, scale):
        return [f"{scale * est.value:.4g}", f"{scale * est.std_error:.2g}"]

    return ([tag, f"{result.quiet_fraction:.3f}"] + pair(c.white_std, 1e6) + pair(c.correlated_std, 1e6)
            + pair(c.correlation_time_s, 1.0) + pair(c.random_walk, 1e6) + [f"{1e6 * c.allan.floor():.3g}"])


def _figure(result, path):
    from sensorplan import plotting

    axes = plotting.plot_allan_deviation(result, attribution=ATTRIBUTION)
    plotting.save_figure(axes[0], path)
    print(f"figure: {path}")


def _write_table(path, rows):
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        fh.write(f"# {ATTRIBUTION}\n# Written by studies/realdata/munich_noise.py; units urad, s, urad/sqrt(s).\n")
        writer = csv.writer(fh)
        writer.writerow(["record", "quiet_fraction", "white_std_urad", "white_se", "correlated_std_urad",
                         "correlated_se", "correlation_time_s", "correlation_time_se", "random_walk_urad_per_sqrt_s",
                         "random_walk_se", "allan_floor_1_30s_urad"])
        writer.writerows(rows)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA_DIR, help="folder of the Munich sample")
    parser.add_argument("--out", type=Path, help="folder for the Allan-deviation figures (default: none)")
    parser.add_argument("--table", type=Path, default=TABLE, help="derived table to write")
    args = parser.parse_args(argv)
    if not (args.data / RECORDS["reference 2022-03-07"][0]).exists():
        print(f"munich_noise: no Munich sample in {args.data}; nothing to do.")
        return 0
    run(args.data, args.out, args.table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
